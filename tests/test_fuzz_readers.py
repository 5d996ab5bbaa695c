"""Hypothesis fuzzing of the readers: mutated sample files raise only flexmor's own errors.

The mutations (delete / duplicate / swap lines, junk / NaN / huge tokens, truncation, binary
prefix) are those of bench/fuzz.py, which runs the same cases by the hundred thousand.
"""

import random
import tempfile
from pathlib import Path

from helpers import ROOT, load_script
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

fuzz = load_script(ROOT / "bench" / "fuzz.py")


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(seed=st.integers(min_value=0, max_value=2**40))
def test_mutated_samples_raise_only_flexmor_errors(seed):
    with tempfile.TemporaryDirectory() as tmp:
        assert fuzz.run_case(seed, Path(tmp)) is None


def test_mutation_changes_bytes():
    rng = random.Random(3)
    data = (fuzz.DATA / "bad" / "mm_nan_K.mtx").read_bytes()
    assert sum(fuzz.mutate(data, rng) != data for _ in range(50)) >= 40
