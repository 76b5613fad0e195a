"""Write docs/bad_input.md from the rows of tests/test_bad_input.py.

Run from the repository root: ``python scripts/bad_input_table.py``.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import test_bad_input  # noqa: E402  (the rows live with their tests)

if __name__ == "__main__":
    test_bad_input.DOC_PAGE.write_text(test_bad_input.table_markdown())
    print(f"wrote {test_bad_input.DOC_PAGE.relative_to(ROOT)}")
