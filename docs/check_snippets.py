"""Run every ```python block of the documentation pages.

The blocks of one page run in order in one namespace, like a notebook, so a
page may build on its earlier blocks.  Blocks fenced as ```text (printed
output) or ```python no-run are skipped.

    MPLBACKEND=Agg python docs/check_snippets.py            # all pages
    MPLBACKEND=Agg python docs/check_snippets.py docs/rk_basis.md

Exits non-zero on the first failing block and names it.
"""

import re
import sys
import time
import traceback
from pathlib import Path

DOCS = Path(__file__).resolve().parent
BLOCK = re.compile(r"^```python[ \t]*(?P<flag>[^\n]*)\n(?P<code>.*?)^```", re.M | re.S)


def blocks(page):
    text = page.read_text()
    for match in BLOCK.finditer(text):
        if "no-run" in match["flag"]:
            continue
        line = text.count("\n", 0, match.start()) + 2
        yield line, match["code"]


def run(page):
    namespace = {"__name__": f"docs_{page.stem}"}
    count = 0
    start = time.perf_counter()
    for line, code in blocks(page):
        try:
            exec(compile(code, f"{page.name}:{line}", "exec"), namespace)
        except Exception:
            traceback.print_exc()
            print(f"FAILED: {page.name}, block starting at line {line}")
            return False
        count += 1
    print(f"ok: {page.name} ({count} blocks, {time.perf_counter() - start:.1f} s)")
    return True


def main(paths):
    pages = [Path(p) for p in paths] or sorted(DOCS.glob("*.md"))
    return 0 if all(run(page) for page in pages) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
