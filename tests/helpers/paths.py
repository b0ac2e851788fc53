"""Where things are: the repository and the tests folder."""

from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
"""The tests folder (``tests/data`` holds the real recordings)."""
ROOT = TESTS.parent
"""The repository."""
EXAMPLES = ROOT / "raw" / "examples"
"""The committed tiny example campaigns."""
