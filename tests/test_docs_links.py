"""Relative links of the documentation point to files and headings that exist.

Checked pages: README.md, docs/*.md and docs/benchmarks/*.md (the tables that
``benchmarks/run_all.py`` writes into docs/benchmarks/runs/ and quick/ are
generated and not checked).  A link ``[text](path#anchor)`` must name an existing
file or folder relative to the page, and, where it has an anchor and points to a
Markdown page, a heading of that page under GitHub's rule: lowercase, characters
other than letters, digits, spaces, ``-`` and ``_`` removed, each space turned
into ``-``, repeated headings numbered ``-1``, ``-2``.  Links inside code blocks
and code spans are not links and are skipped, as are web addresses.
"""

import re
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md"),
                *(ROOT / "docs" / "benchmarks").glob("*.md")])

FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.M | re.S)
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1", re.S)
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)[ \t#]*$", re.M)


def prose(text):
    """The text without fenced code blocks (their lines kept, emptied)."""
    return FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)


def slug(heading):
    """GitHub's anchor of a heading's text."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)   # links: their text
    text = text.replace("`", "")
    kept = []
    for ch in text.lower():
        if ch in " -_" or unicodedata.category(ch)[0] in "LN":
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def anchors(page):
    found, seen = set(), {}
    for match in HEADING.finditer(prose(page.read_text())):
        base = slug(match.group(2))
        n = seen.get(base, 0)
        seen[base] = n + 1
        found.add(base if n == 0 else f"{base}-{n}")
    return found


def links(page):
    text = CODE_SPAN.sub("", prose(page.read_text()))
    for match in LINK.finditer(text):
        target = match.group(1)
        if not target or re.match(r"[a-z][a-z0-9+.-]*:", target, re.I):
            continue    # web addresses, mailto:
        line = text.count("\n", 0, match.start()) + 1
        yield line, target


def test_slug_follows_github():
    assert slug("3. Integration: Gauss cells and VCI") == "3-integration-gauss-cells-and-vci"
    assert slug("Any form, fast: `skfem_rkpm.asm`") == "any-form-fast-skfem_rkpmasm"
    assert slug('Which locking control: `discretization.locking = "auto"`') == \
        "which-locking-control-discretizationlocking--auto"
    assert slug("Fewer tangents (December 2026, second round)") == \
        "fewer-tangents-december-2026-second-round"


def test_pages_are_found():
    names = {p.relative_to(ROOT).as_posix() for p in PAGES}
    assert {"README.md", "docs/index.md", "docs/performance.md",
            "docs/benchmarks/linear_solvers.md"} <= names


def broken_links(page, root=ROOT):
    """The links of ``page`` whose file or heading does not exist."""
    broken, cache = [], {}
    for line, target in links(page):
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        shown = dest.relative_to(root) if dest.is_relative_to(root) else dest
        if not dest.exists():
            broken.append(f"line {line}: {target} (no file {shown})")
        elif anchor and dest.suffix == ".md":
            if dest not in cache:
                cache[dest] = anchors(dest)
            if anchor not in cache[dest]:
                broken.append(f"line {line}: {target} (no heading with anchor #{anchor} "
                              f"in {shown})")
    return broken


def test_broken_links_are_found(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "a.png").write_bytes(b"")
    (tmp_path / "other.md").write_text("# Other page\n\n## A heading: with `code`\n\n"
                                       "## A heading: with `code`\n")
    page = tmp_path / "sub" / "page.md"
    page.write_text("# Page\n\n"
                    "![ok](../figures/a.png) ![moved](figures/a.png)\n"
                    "[ok](../other.md#a-heading-with-code) [ok](../other.md#a-heading-with-code-1)\n"
                    "[no heading](../other.md#a-heading) [here](#page) [not here](#other-page)\n"
                    "[web](https://example.org/x.md#y) `[code](missing.md)`\n"
                    "```text\n[block](missing.md)\n```\n")
    found = broken_links(page, tmp_path)
    assert [entry.split(" (")[0] for entry in found] == [
        "line 3: figures/a.png", "line 5: ../other.md#a-heading", "line 5: #other-page"]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(page):
    broken = broken_links(page)
    assert not broken, f"{page.relative_to(ROOT)}: broken links\n" + "\n".join(broken)
