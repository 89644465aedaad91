"""The fuzz harness's modules (fuzz_cases, fuzz_runner) are imported by name (--import-mode=importlib);
bench/bench_fuzz.py imports them the same way."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
