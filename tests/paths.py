"""Paths the tests share: this folder (on sys.path, see conftest.py) and the repository root."""
from pathlib import Path

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
