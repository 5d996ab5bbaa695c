"""Fuzz flexmor's readers with structured mutations of the real sample files.

Each case copies one sample set (e.g. a CalculiX ``.sti`` + ``.mas`` + ``.dof`` + ``.inp``) into a
scratch folder, mutates one of its files (delete / duplicate / swap lines, replace a token with
junk, NaN or a huge integer, truncate at a random byte, prepend binary junk) and reads it with
``flexmor.io.read``. A finding is any exception that is not a :class:`flexmor.errors.FlexmorError`
(or a case slower than ``--timeout`` seconds), and any case that kills its worker process (a
crash in compiled code, e.g. a segmentation fault): each chunk of cases runs in its own process,
which publishes the seed it is reading, so a dead or stuck worker names the case and the run
goes on with the next seed. Findings are printed as they occur.
``python bench/fuzz.py -n 100000 -j 2``.
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


def _chunk(start, count, timeout, current, conn):
    """Run seeds ``start .. start+count-1`` in this (child) process.

    ``current`` holds the seed being read, so that the parent can name it when the process
    dies (a crash in compiled code) or stops making progress; findings are sent at once.
    """
    import logging
    import signal
    logging.disable(logging.CRITICAL)
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(start, start + count):
            current.value = seed
            signal.alarm(timeout)
            try:
                r = run_case(seed, Path(tmp))
            except _Timeout:
                r = f"seed {seed} {TARGETS[seed % len(TARGETS)][0]}: hang: longer than {timeout} s at -"
            finally:
                signal.alarm(0)
            if r:
                conn.send(("finding", r))
    conn.send(("done", count))
    conn.close()


def _target(seed: int) -> str:
    return TARGETS[seed % len(TARGETS)][0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=100_000, help="number of cases")
    ap.add_argument("-j", type=int, default=2, help="worker processes")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--chunk", type=int, default=2000, help="cases per worker process")
    ap.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds (report the count)")
    ap.add_argument("--timeout", type=int, default=20, help="seconds per case before it counts as a hang")
    a = ap.parse_args(argv)
    import signal as _signal
    from collections import deque
    from multiprocessing.connection import wait

    t0 = time.perf_counter()
    ctx = mp.get_context("spawn")
    pending = deque((s, min(a.chunk, a.seed + a.n - s)) for s in range(a.seed, a.seed + a.n, a.chunk))
    running = []  # [process, pipe, current seed, first seed, count, (seed, since)]
    done, findings = 0, []

    def finding(text):
        findings.append(text)
        print(text, flush=True)

    def drain(r):
        while r[1].poll():
            try:
                kind, val = r[1].recv()
            except EOFError:
                return False
            if kind == "finding":
                finding(val)
            else:
                return True
        return False

    stopped = False
    while pending or running:
        while pending and len(running) < a.j and not stopped:
            start, count = pending.popleft()
            current = ctx.Value("q", start - 1, lock=False)
            rd, wr = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_chunk, args=(start, count, a.timeout, current, wr), daemon=True)
            proc.start()
            wr.close()
            running.append([proc, rd, current, start, count, (start - 1, time.perf_counter())])
        wait([r[0].sentinel for r in running] + [r[1] for r in running], timeout=1.0)
        for r in list(running):
            proc, rd, current, start, count, (seen, since) = r
            if drain(r):
                proc.join()
                running.remove(r)
                done += count
                continue
            seed = current.value
            if proc.is_alive():
                now = time.perf_counter()
                if seed != seen:
                    r[5] = (seed, now)
                elif now - since > 3 * a.timeout + 30:  # stuck where SIGALRM cannot interrupt
                    proc.kill()
                    proc.join()
                    drain(r)
                    finding(f"seed {seed} {_target(seed)}: hang: no progress for {now - since:.0f} s (killed) at -")
                    running.remove(r)
                    done += seed - start + 1
                    if start + count > seed + 1:
                        pending.appendleft((seed + 1, start + count - seed - 1))
                continue
            proc.join()
            drain(r)
            running.remove(r)
            code = proc.exitcode
            how = f"signal {_signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            finding(f"seed {seed} {_target(seed)}: crash: the process died ({how}) at -")
            done += seed - start + 1
            if start + count > seed + 1:
                pending.appendleft((seed + 1, start + count - seed - 1))
        if a.time_limit and time.perf_counter() - t0 > a.time_limit and not stopped:
            stopped = True
            pending.clear()
            for r in running:
                r[0].kill()
                r[0].join()
                drain(r)
                done += max(0, r[2].value - r[3])  # cases finished before the one it was reading
            running = []
        print(f"\r{done + sum(max(0, r[2].value - r[3]) for r in running)} cases, {len(findings)} findings, "
              f"{time.perf_counter() - t0:.0f} s", end="", file=sys.stderr, flush=True)
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
