"""Fuzz flexmor's readers with structured mutations of the real sample files.

Each case copies one sample set (e.g. a CalculiX ``.sti`` + ``.mas`` + ``.dof`` + ``.inp``) into a
scratch folder, mutates one of its files (delete / duplicate / swap lines, replace a token with
junk, NaN or a huge integer, truncate at a random byte, prepend binary junk) and reads it with
``flexmor.io.read``. A finding is any exception that is not a :class:`flexmor.errors.FlexmorError`
(or a case slower than ``--timeout`` seconds). ``python bench/fuzz.py -n 100000 -j 2``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import random
import shutil
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"

#: (main file, [files that may be mutated]) relative to tests/data; small samples only.
TARGETS = [
    ("calculix/beam8_clamped_mat.sti", ["calculix/beam8_clamped_mat.sti", "calculix/beam8_clamped_mat.mas",
                                        "calculix/beam8_clamped_mat.dof", "calculix/beam8_clamped_mat.inp"]),
    ("nastran/pyyeti_rd_ascii.op4", ["nastran/pyyeti_rd_ascii.op4"]),
    ("sid/balken1m.SID_FEM", ["sid/balken1m.SID_FEM"]),
    ("mor/LF10.mat", ["mor/LF10.mat"]),
    ("bad/mm_nan_K.mtx", ["bad/mm_nan_K.mtx", "bad/mm_nan_M.mtx"]),
    ("ansys/rotorAnsysMassMatrixSparse.txt", ["ansys/rotorAnsysMassMatrixSparse.txt",
                                              "ansys/rotorAnsysStiffnessMatrixSparse.txt",
                                              "ansys/rotorAnsysMatrixDofMappingVector.txt",
                                              "ansys/rotorAnsysNodalCoordinates.txt"]),
    ("bad/abq_inf.inp", ["bad/abq_inf.inp", "bad/abq_inf_STIF1.mtx", "bad/abq_inf_MASS1.mtx"]),
]
# the Matrix Market and Abaqus seeds above are the corpus' tiny models; repair their one defect first
_REPAIR = {"bad/mm_nan_K.mtx": (b"2 2 NaN", b"2 2 2.0"), "bad/abq_inf_STIF1.mtx": (b"-inf", b"2.0e6")}
JUNK = [b"nan", b"NaN", b"inf", b"-inf", b"1e999", b"99999999999999999999", b"-1", b"0", b"x", b"",
        b"1.0.0", b"\x00\xff", b"1,5", b"*NODE", b"%%MatrixMarket", b"1e-320", b"3.5"]


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One random structured mutation of ``data``."""
    lines = data.splitlines(keepends=True) or [b""]
    kind = rng.randrange(8)
    i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
    if kind == 0:
        del lines[i]
    elif kind == 1:
        lines.insert(i, lines[j])
    elif kind == 2:
        lines[i], lines[j] = lines[j], lines[i]
    elif kind in (3, 4):
        toks = lines[i].split(b" ") if b" " in lines[i] else lines[i].split(b",")
        sep = b" " if b" " in lines[i] else b","
        k = rng.randrange(len(toks))
        toks[k] = rng.choice(JUNK) + (b"\n" if toks[k].endswith(b"\n") else b"")
        lines[i] = sep.join(toks)
    elif kind == 5:
        return data[: rng.randrange(len(data) + 1)]
    elif kind == 6:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200))) + data
    else:
        pos = rng.randrange(len(data) + 1)
        return data[:pos] + bytes([rng.randrange(256)]) + data[pos + 1:]
    return b"".join(lines)


def run_case(seed: int, folder: Path):
    """Mutate and read one case in ``folder``; returns None or a finding string."""
    import flexmor.io
    from flexmor.errors import FlexmorError

    rng = random.Random(seed)
    main, files = TARGETS[seed % len(TARGETS)]
    for p in folder.iterdir():
        p.unlink()
    for f in files:
        raw = (DATA / f).read_bytes()
        if f in _REPAIR:
            raw = raw.replace(*_REPAIR[f])
        (folder / Path(f).name).write_bytes(raw)
    victim = folder / Path(rng.choice(files)).name
    data = victim.read_bytes()
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        data = mutate(data, rng)
    victim.write_bytes(data)
    fmt = "ansys" if main.startswith("ansys") else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if main.endswith(".op4"):  # the sample's matrices are not a model: fuzz the OP4 parser itself
                from flexmor.io.nastran import read_op4
                read_op4(folder / Path(main).name)
            else:
                flexmor.io.read(folder / Path(main).name, format=fmt)
    except FlexmorError:
        return None
    except Exception as exc:  # noqa: BLE001 - this is what we look for
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return f"seed {seed} {main} ({victim.name}): {type(exc).__name__}: {str(exc)[:120]} at {tb.filename}:{tb.lineno}"
    return None


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout


def _worker(args):
    start, count, timeout = args
    import logging
    import signal
    logging.disable(logging.CRITICAL)
    signal.signal(signal.SIGALRM, _alarm)
    found = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(start, start + count):
            signal.alarm(timeout)
            try:
                r = run_case(seed, Path(tmp))
            except _Timeout:
                r = f"seed {seed} {TARGETS[seed % len(TARGETS)][0]}: hang: longer than {timeout} s at -"
            finally:
                signal.alarm(0)
            if r:
                found.append(r)
    return count, found


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=100_000, help="number of cases")
    ap.add_argument("-j", type=int, default=2, help="worker processes")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--chunk", type=int, default=500)
    ap.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds (report the count)")
    ap.add_argument("--timeout", type=int, default=20, help="seconds per case before it counts as a hang")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    chunks = [(s, min(a.chunk, a.seed + a.n - s), a.timeout) for s in range(a.seed, a.seed + a.n, a.chunk)]
    done, findings = 0, []
    with mp.get_context("spawn").Pool(a.j) as pool:
        for count, found in pool.imap_unordered(_worker, chunks):
            done += count
            findings += found
            if a.time_limit and time.perf_counter() - t0 > a.time_limit:
                pool.terminate()
                break
            print(f"\r{done} cases, {len(findings)} findings, {time.perf_counter() - t0:.0f} s", end="",
                  file=sys.stderr, flush=True)
    print(file=sys.stderr)
    kinds = {}
    for f in findings:
        kinds.setdefault(f.split(": ", 1)[1].split(" at ")[-1], []).append(f)
    print(f"cases {done}  findings {len(findings)}  distinct sites {len(kinds)}  time {time.perf_counter() - t0:.1f} s")
    for site, fs in sorted(kinds.items(), key=lambda kv: -len(kv[1])):
        print(f"  {len(fs):6d}x {fs[0]}")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
