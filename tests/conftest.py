"""Shared test setup: the helpers (`helpers.py`), the plain-Python twin (`reference.py`) and a
user's module (`user_components.py`) are importable from every test folder."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent))
