"""Hypothesis fuzzing of the readers: mutated sample files raise only flexmor's own errors.

The mutations (delete / duplicate / swap lines, junk / NaN / huge tokens, truncation, binary
prefix) are those of bench/fuzz.py, which runs the same cases by the hundred thousand.
"""

import importlib.util
import random
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_spec = importlib.util.spec_from_file_location("fuzz", Path(__file__).parent.parent / "bench" / "fuzz.py")
fuzz = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fuzz)


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(seed=st.integers(min_value=0, max_value=2**40))
def test_mutated_samples_raise_only_flexmor_errors(seed):
    with tempfile.TemporaryDirectory() as tmp:
        assert fuzz.run_case(seed, Path(tmp)) is None


def test_mutation_changes_bytes():
    rng = random.Random(3)
    data = (fuzz.DATA / "bad" / "mm_nan_K.mtx").read_bytes()
    assert sum(fuzz.mutate(data, rng) != data for _ in range(50)) >= 40
