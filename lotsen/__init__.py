"""lotsen ("the pilot"): model-based autonomy for small surface vessels."""

__version__ = "0.1.0"
