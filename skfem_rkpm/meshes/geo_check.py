"""Refuse gmsh ``.geo`` scripts that reach outside their own geometry.

A ``.geo`` file is a program that gmsh runs: besides points, curves and
mesh options it can run programs (``SystemCall "rm -rf ~";``), read other
files (``Include``, ``Merge``) and write or delete files.  A scene from
someone else must not do that, so :func:`unsafe_geo_commands` scans the
script (comments and string contents left out) for the commands and options
of gmsh's ``.geo`` language that do, and :func:`check_geo` refuses a file
that has any, naming the file, the line and the command.  A file you trust
passes with ``trust_geo=True`` (``--trust-geo`` on the command line).

The list (gmsh 4 ``.geo`` language, ``Gmsh.y``/``Gmsh.l``):

* run programs: ``SystemCall``, ``NonBlockingSystemCall``, ``System``,
  ``OnelabRun``, the ``ExternalProcess`` mesh-size field, ``Plugin(...)``
  (plugins read, write and run), and any ``Solver.*`` option (solver
  executables and their command lines);
* read other files: ``Include``, ``Merge``, ``MergeWithBoundingBox``,
  ``ShapeFromFile``, ``Import``, the ``Structured`` field (reads a grid
  file), ``GetEnv``, ``FileExists`` and any option whose name contains
  ``FileName``;
* write or delete files, or end the process: ``Save``, ``Print``,
  ``Printf(...) > "file"`` (a redirected ``Printf``), ``CreateDir``,
  ``DeleteFile``, ``RenameFile``, ``Exit``, ``Abort``.
"""

import re

__all__ = ["GEO_COMMANDS", "unsafe_geo_commands", "check_geo"]

RUNS = "runs a program"
READS = "reads another file"
WRITES = "writes or deletes files, or ends the process"

#: commands (whole words) and what they do
GEO_COMMANDS = {
    "SystemCall": RUNS, "NonBlockingSystemCall": RUNS, "System": RUNS,
    "OnelabRun": RUNS, "ExternalProcess": RUNS, "Plugin": RUNS,
    "Include": READS, "Merge": READS, "MergeWithBoundingBox": READS,
    "ShapeFromFile": READS, "Import": READS, "Structured": READS, "GetEnv": READS,
    "FileExists": READS,
    "Save": WRITES, "Print": WRITES, "CreateDir": WRITES, "DeleteFile": WRITES,
    "RenameFile": WRITES, "Exit": WRITES, "Abort": WRITES,
}
_LOWER = {k.lower(): k for k in GEO_COMMANDS}


def _code_only(text):
    """``text`` with comments and string contents blanked (lines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append('"' + re.sub(r"[^\n]", " ", text[i + 1:j - 1]) + '"')
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def unsafe_geo_commands(text):
    """``[(line, command, what it does), ...]`` of the commands and options
    in ``.geo`` text that run programs, read other files or write files."""
    code = _code_only(text)
    found = []
    for match in re.finditer(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*", code):
        word = match.group(0)
        line = code.count("\n", 0, match.start()) + 1
        first = word.split(".")[0]
        if "." not in word and word.lower() in _LOWER:
            command = _LOWER[word.lower()]
            found.append((line, word, GEO_COMMANDS[command]))
        elif "." in word and first.lower() == "solver":
            found.append((line, word, RUNS))
        elif "." in word and any(s in word.lower() for s in ("filename", "executable")):
            found.append((line, word, READS))
        elif word == "Printf":
            rest = code[match.end():]
            close = _closing_parenthesis(rest)
            if close is not None and rest[close + 1:].lstrip().startswith(">"):
                found.append((line, "Printf > file", WRITES))
    return found


def _closing_parenthesis(text):
    depth = 0
    for k, c in enumerate(text):
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                return k
        elif c == ";" and depth == 0:
            return None
    return None


def check_geo(path, text, trust_geo=False):
    """Raise ``ValueError`` if the ``.geo`` ``text`` of ``path`` runs programs,
    reads other files or writes files (see :data:`GEO_COMMANDS`), unless
    ``trust_geo``."""
    if trust_geo:
        return
    found = unsafe_geo_commands(text)
    if found:
        line, command, what = found[0]
        more = f" (and {len(found) - 1} more such commands)" if len(found) > 1 else ""
        raise ValueError(
            f"{path}, line {line}: {command} {what}{more}; a .geo file that runs "
            f"programs or reads or writes other files is refused. Mesh it yourself "
            f"and use the .msh file, or, if you trust the file, pass --trust-geo "
            f"(trust_geo=True)")
