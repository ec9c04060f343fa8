"""Helpers shared by the Python tests (importable as ``support``: pyproject's
pytest ``pythonpath`` puts tests/python on sys.path): paths, the scenes several
integrator tests render, and the statistics they compare with."""
from pathlib import Path

#: the repository root, tests/data/usd, sequences/
ROOT = Path(__file__).resolve().parents[3]
DATA_USD = ROOT / "tests" / "data" / "usd"
SEQUENCES = ROOT / "sequences"
