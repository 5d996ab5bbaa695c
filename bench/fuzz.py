"""Fuzz flexmor's readers with structured mutations of real files; classify every outcome.

Each case copies one sample set (e.g. a CalculiX ``.sti`` + ``.mas`` + ``.dof`` + ``.inp``, or
the same set gzip-compressed) into a scratch folder, damages one of its files (see
:func:`mutate`: cut at a line end or at a byte, delete / duplicate / swap lines or blocks of
lines, NaN / Inf / overflowing numbers, header counts changed, binary garbage) and reads it.
The outcome is one of

``refused``
    a :class:`flexmor.errors.FlexmorError` (the clean refusal);
``warned``
    read, with a FlexmorWarning or a logged warning that the unmutated set does not give;
``warned-unverifiable``
    read as another model, with the :class:`flexmor.io.UncheckedWarning` that the reader gives on
    every read of the damaged file, whose format cannot show such a damage (it names the file and
    what could not be cross-checked);
``equal``
    read without a new warning, and the model equals the one of the unmutated set (same
    ``n_dof``, ``K``, ``M`` and ``D`` to round-off, same equation map, same node table);
``silent-different``
    read without a new warning, and another model: a finding;
``crash``
    any other exception, a worker process that died (a crash in compiled code) or a case
    slower than ``--timeout`` seconds: a finding.

Each chunk of cases runs in its own process, which publishes the seed it is reading, so a dead
or stuck worker names the case and the run goes on with the next seed. Findings are printed as
they occur; the closing table counts each class per target (``--markdown`` prints it as a
Markdown table), ``--group`` lists the silent-different and warned-unverifiable cases grouped by
target, file and mutation (count and first seed). ``python bench/fuzz.py -n 100000 -j 2``.
"""

from __future__ import annotations

import argparse
import atexit
import gzip
import logging
import multiprocessing as mp
import random
import re
import shutil
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
CLASSES = ("refused", "warned", "warned-unverifiable", "equal", "silent-different", "crash")
FINDINGS = ("silent-different", "crash")


@dataclass(frozen=True)
class Target:
    """A sample set: ``main`` is read, one of ``files`` (paths relative to tests/data, or
    ``gen:NAME`` for a file built from a sample by :func:`_generate`) is mutated."""

    name: str
    main: str
    files: tuple
    format: str | None = None
    gz: bool = False  # every file of the set gzip-compressed
    op4: bool = False  # read with read_op4 (all matrices of the file), not as a model


_CCX = tuple(f"calculix/beam8_clamped_mat{s}" for s in (".sti", ".mas", ".dof", ".inp"))
TARGETS = [
    Target("calculix", _CCX[0], _CCX),
    Target("calculix.gz", _CCX[0], _CCX, gz=True),
    Target("abaqus", "abaqus/blockC3D8.inp", ("abaqus/blockC3D8.inp", "abaqus/blockC3D8_STIF1.mtx",
                                                "abaqus/blockC3D8_MASS1.mtx")),
    Target("matrix-market", "bad/mm_nan_K.mtx", ("bad/mm_nan_K.mtx", "bad/mm_nan_M.mtx")),
    Target("nastran-dmig", "gen:beam.pch", ("gen:beam.pch", "gen:beam.bdf")),
    Target("op4-ascii", "gen:beam.op4", ("gen:beam.op4",), op4=True),
    Target("op4-binary", "gen:beamb.op4", ("gen:beamb.op4",), op4=True),
    Target("op4-pyyeti", "nastran/pyyeti_rd_ascii.op4", ("nastran/pyyeti_rd_ascii.op4",), op4=True),
    Target("ansys-txt", "ansys/rotorAnsysMassMatrixSparse.txt",
           ("ansys/rotorAnsysMassMatrixSparse.txt", "ansys/rotorAnsysStiffnessMatrixSparse.txt",
            "ansys/rotorAnsysMatrixDofMappingVector.txt", "ansys/rotorAnsysNodalCoordinates.txt"), format="ansys"),
    Target("ansys-full", "ansys/ansys_file.full", ("ansys/ansys_file.full",)),
    Target("sid", "sid/balken1m.SID_FEM", ("sid/balken1m.SID_FEM",)),
    Target("matlab", "mor/LF10.mat", ("mor/LF10.mat",)),
]
# the Matrix Market seed is one of the corpus' tiny models: repair its one defect first
_REPAIR = {"bad/mm_nan_K.mtx": (b"2 2 NaN", b"2 2 2.0")}
#: Replacement tokens: each malformed, not a number, or a number that overflows / is not finite.
JUNK = [b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"1e999", b"-1e400", b"1.0e+9999",
        b"x", b"", b"1.0.0", b"\x00\xff", b"1,5,", b"*NODE", b"%%MatrixMarket", b"1e", b"--1", b"0x1F"]
#: Cut positions: the fraction of lines kept (a reported cut .sti kept 6950 of 6984 lines).
CUT_KEEP = (0.0, 0.5, 0.9, 0.95, 0.98, 0.99, 0.995)
_GEN: dict = {}


def _generate(folder: Path) -> None:
    """Files built from a sample: the clamped beam's K and M as DMIG (with its GRIDs) and as OP4."""
    import numpy as np
    import scipy.sparse as sp

    import flexmor.io

    sys.path.insert(0, str(ROOT / "tests"))
    from op4_writer import write_ascii, write_binary

    m = flexmor.io.read(DATA / _CCX[0])
    lines = []
    for name, A in (("KAAX", m.K), ("MAAX", m.M)):
        U = sp.triu(A).tocsc()
        lines.append(f"DMIG    {name:<8}{0:8d}{6:8d}{2:8d}{0:8d}")
        for j in range(U.shape[1]):
            g, d = m.dofs[j]
            lines.append(f"DMIG*   {name:<16}{g:>16}{d:>16}")
            lines += [f"*       {m.dofs[i, 0]:>16}{m.dofs[i, 1]:>16}{v:16.9E}".replace("E", "D")
                      for i, v in zip(U.indices[U.indptr[j]:U.indptr[j + 1]].tolist(),
                                      U.data[U.indptr[j]:U.indptr[j + 1]].tolist())]
    (folder / "beam.pch").write_text("\n".join(lines) + "\n")
    used = np.isin(m.node_ids, m.dofs[:, 0])
    (folder / "beam.bdf").write_text("".join(f"GRID,{i},,{x!r},{y!r},{z!r}\n" for i, (x, y, z)
                                             in zip(m.node_ids[used].tolist(), m.xyz[used].tolist())))
    mats = {"KAAX": m.K.toarray()[:60, :60], "MAAX": m.M.toarray()[:60, :60]}
    write_ascii(folder / "beam.op4", mats, sparse=True, form=6)  # symmetric, stored in full as Nastran does
    write_binary(folder / "beamb.op4", mats)


def _source(f: str) -> Path:
    if f.startswith("gen:"):
        if "dir" not in _GEN:
            _GEN["dir"] = Path(tempfile.mkdtemp(prefix="flexmor-fuzz-gen-"))
            atexit.register(shutil.rmtree, _GEN["dir"], True)
            _generate(_GEN["dir"])
        return _GEN["dir"] / f[4:]
    return DATA / f


def _name(t: Target, f: str) -> str:
    return Path(f[4:] if f.startswith("gen:") else f).name + (".gz" if t.gz else "")


def _lines(data: bytes) -> list:
    return data.splitlines(keepends=True) or [b""]


def _number_tokens(line: bytes) -> list:
    """Indices of the tokens of ``line`` (split at blanks and commas) that hold a digit."""
    toks = line.replace(b",", b" ").split(b" ")
    return [k for k, t in enumerate(toks) if any(48 <= c <= 57 for c in t)]


def _replace_token(line: bytes, rng: random.Random, new=None, integer=False) -> bytes:
    sep = b"," if b"," in line and b" " not in line.strip() else b" "
    toks = line.split(sep)
    nums = [k for k, t in enumerate(toks) if (_INTEGER.fullmatch(t) if integer else any(48 <= c <= 57 for c in t))]
    if not nums:
        return line if integer else line[:-1] + rng.choice(JUNK) + line[-1:]
    k = rng.choice(nums)
    end = b"\n" if toks[k].endswith(b"\n") else b""
    if new is None:  # an integer too large for any index, but only where an integer stands
        new = (lambda _t: rng.choice(JUNK + [b"99999999999999999999"])) if _INTEGER.fullmatch(toks[k]) else (
            lambda _t: rng.choice(JUNK))
    toks[k] = new(toks[k].strip()) + end
    return sep.join(toks)


_INTEGER = re.compile(rb"\s*[+-]?\d+[,;]?\s*")


def _wrong_count(tok: bytes, rng: random.Random) -> bytes:
    """``tok`` with its first integer changed (one more or less, doubled, halved, zero, negative ...)."""
    m = re.search(rb"\d+", tok)
    if m is None:
        return tok + b"1"
    v = int(m.group())
    new = str(rng.choice((v + 1, v - 1, 2 * v, v // 2, 0, v + 1000, -v))).encode()
    return tok[:m.start()] + new + tok[m.end():]


def _integer_tokens(line: bytes) -> bool:
    sep = b"," if b"," in line and b" " not in line.strip() else b" "
    return any(_INTEGER.fullmatch(t) for t in line.split(sep))


#: Mutations that leave a damage a format can show: a cut, lost or repeated lines, non-numbers,
#: foreign bytes around the text. The others (swapped lines, a changed count or index, a changed
#: byte) can turn a valid file into another valid file of another model.
STRUCTURAL = ("cut-lines", "cut-bytes", "delete", "delete-block", "duplicate", "duplicate-block", "junk", "nonfinite",
              "garbage-prepend", "garbage-append")
MUTATIONS = ("cut-lines", "cut-bytes", "delete", "delete-block", "duplicate", "duplicate-block", "swap", "junk",
             "nonfinite", "count", "garbage-prepend", "garbage-insert", "garbage-byte", "garbage-append")


def mutate(data: bytes, rng: random.Random, kind: str | None = None) -> bytes:
    """One structured mutation of ``data`` (``kind`` from :data:`MUTATIONS`, random by default)."""
    kind = kind or rng.choice(MUTATIONS)
    lines = _lines(data)
    n = len(lines)
    i, j = rng.randrange(n), rng.randrange(n)
    if kind == "cut-lines":  # at a line end: what an interrupted copy often leaves
        keep = rng.choice(CUT_KEEP + (None,))
        k = rng.randrange(n) if keep is None else int(n * keep)
        return b"".join(lines[:k] if k < n else lines[:-1])
    if kind == "cut-bytes":
        return data[: rng.randrange(len(data) + 1)]
    if kind == "delete":
        del lines[i]
    elif kind == "delete-block":
        del lines[i:i + rng.randint(2, max(2, n // 10))]
    elif kind == "duplicate":
        lines.insert(i, lines[j])
    elif kind == "duplicate-block":
        k = rng.randint(2, max(2, n // 10))
        lines[i:i] = lines[j:j + k]
    elif kind == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    elif kind == "junk":
        lines[i] = _replace_token(lines[i], rng)
    elif kind == "nonfinite":
        cands = [k for k in rng.sample(range(n), min(n, 20)) if _number_tokens(lines[k])] or [i]
        k = rng.choice(cands)
        lines[k] = _replace_token(lines[k], rng, lambda _t: rng.choice((b"NaN", b"-Inf", b"1.0e+999", b"-2e400")))
    elif kind == "count":  # a count or index changed: an integer in the first lines (a header) or anywhere
        head = [k for k in range(min(n, 8)) if _integer_tokens(lines[k])]
        if not head or rng.random() < 0.3:
            head = [k for k in rng.sample(range(n), min(n, 20)) if _integer_tokens(lines[k])]
        if not head:
            return data
        k = rng.choice(head)
        lines[k] = _replace_token(lines[k], rng, lambda t: _wrong_count(t, rng), integer=True)
    elif kind == "garbage-prepend":
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200))) + data
    elif kind == "garbage-insert":
        pos = rng.randrange(len(data) + 1)
        return data[:pos] + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64))) + data[pos:]
    elif kind == "garbage-append":
        return data + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
    else:  # garbage-byte
        pos = rng.randrange(len(data) + 1)
        return data[:pos] + bytes([rng.randrange(256)]) + data[pos + 1:]
    return b"".join(lines)


def _setup(t: Target, folder: Path) -> dict:
    """Copy the unmutated set into ``folder``; returns its plain bytes by file name."""
    for p in folder.iterdir():
        p.unlink()
    plain = {}
    for f in t.files:
        raw = _source(f).read_bytes()
        if f in _REPAIR:
            raw = raw.replace(*_REPAIR[f])
        plain[f] = raw
        (folder / _name(t, f)).write_bytes(gzip.compress(raw, mtime=0) if t.gz else raw)
    return plain


class _Log(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def _read(t: Target, folder: Path):
    """``(result, warning messages, unchecked-read messages)`` of reading the set in ``folder`` (paths in the
    messages blanked)."""
    import flexmor.io

    handler = _Log()
    logger = logging.getLogger("flexmor")
    logger.addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            main = folder / _name(t, t.main)
            if t.op4:
                from flexmor.io.nastran import read_op4
                out = read_op4(main)
            else:
                out = flexmor.io.read(main, format=t.format)
    finally:
        logger.removeHandler(handler)
    from flexmor.errors import FlexmorWarning
    from flexmor.io import UncheckedWarning
    msgs = [str(w.message) for w in caught if issubclass(w.category, FlexmorWarning)
            and not issubclass(w.category, UncheckedWarning)] + handler.messages
    unchecked = [str(w.message) for w in caught if issubclass(w.category, UncheckedWarning)]
    return out, {m.replace(str(folder), "") for m in msgs}, {m.replace(str(folder), "") for m in unchecked}


def _close(A, B) -> bool:
    import numpy as np
    import scipy.sparse as sp

    if A is None or B is None:
        return A is None and B is None
    if A.shape != B.shape:
        return False
    A = A.toarray() if sp.issparse(A) else np.asarray(A)
    B = B.toarray() if sp.issparse(B) else np.asarray(B)
    if A.dtype.kind != B.dtype.kind and "c" in (A.dtype.kind, B.dtype.kind):
        return False
    scale = max(float(np.abs(B).max(initial=0.0)), 1e-300)
    return bool(np.all(np.isfinite(A)) and np.abs(A - B).max(initial=0.0) <= 1e-12 * scale)


def same_model(a, b) -> bool:
    """Whether two read results are the same model (or the same OP4 matrices) to round-off."""
    import numpy as np

    if isinstance(b, dict):
        return isinstance(a, dict) and a.keys() == b.keys() and all(_close(a[k], b[k]) for k in b)
    if a.n_dof != b.n_dof or not all(_close(getattr(a, r), getattr(b, r)) for r in ("K", "M", "D")):
        return False
    if (a.dofs is None) != (b.dofs is None) or (b.dofs is not None and not np.array_equal(a.dofs, b.dofs)):
        return False
    oa, ob = np.argsort(a.node_ids, kind="stable"), np.argsort(b.node_ids, kind="stable")
    return bool(np.array_equal(a.node_ids[oa], b.node_ids[ob]) and a.xyz.shape == b.xyz.shape
                and _close(a.xyz[oa], b.xyz[ob]))  # to 1e-12 of the model's extent, as the matrices


_REFERENCE: dict = {}


def reference(t: Target, folder: Path):
    """The result and warnings of the unmutated set (read once per process)."""
    if t.name not in _REFERENCE:
        _setup(t, folder)
        _REFERENCE[t.name] = _read(t, folder)
    return _REFERENCE[t.name]


def target_of(seed: int, targets=None) -> Target:
    """The target of case ``seed`` among ``targets`` (names; all by default)."""
    pool = [t for t in TARGETS if targets is None or t.name in targets]
    return pool[seed % len(pool)]


def run_case(seed: int, folder: Path, targets=None, mutations=MUTATIONS):
    """Mutate and read one case in ``folder``; returns ``(class, description)``.

    ``targets`` (names) and ``mutations`` narrow the cases (all by default): seed ``s`` takes
    target ``s mod len(targets)``.
    """
    from flexmor.errors import FlexmorError

    rng = random.Random(seed)
    t = target_of(seed, targets)
    ref, ref_warnings, _ = reference(t, folder)
    plain = _setup(t, folder)
    f = rng.choice(t.files)
    victim = folder / _name(t, f)
    data = plain[f]
    kinds = []
    if t.gz and rng.random() < 0.25:  # damage the compressed bytes themselves
        data = gzip.compress(data, mtime=0)
        kinds.append("gz:" + rng.choice(("cut-bytes", "garbage-byte", "garbage-append", "garbage-insert")))
        data = mutate(data, rng, kinds[-1][3:])
    else:
        for _ in range(rng.choice((1, 1, 1, 2, 3))):
            kinds.append(rng.choice(mutations))
            data = mutate(data, rng, kinds[-1])
        if t.gz:
            data = gzip.compress(data, mtime=0)
    victim.write_bytes(data)
    what = f"seed {seed} {t.name} ({victim.name}: {'+'.join(kinds)})"
    try:
        got, msgs, unchecked = _read(t, folder)
    except FlexmorError as exc:
        return "refused", f"{what}: {str(exc).replace(str(folder) + '/', '')[:160]}"
    except Exception as exc:  # noqa: BLE001 - this is what we look for
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        return "crash", f"{what}: {type(exc).__name__}: {str(exc)[:120]} at {tb.filename}:{tb.lineno}"
    new = msgs - ref_warnings
    if new:
        return "warned", f"{what}: {sorted(new)[0][:160]}"
    if same_model(got, ref):
        return "equal", what
    mine = sorted(m for m in unchecked if victim.name in m.split(": ")[0].split(", "))
    if mine:  # the damaged file is one whose reader said what it could not cross-check
        return "warned-unverifiable", f"{what}: {mine[0][:160]}"
    return "silent-different", what


class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout


#: The classes whose cases the parent is told about one by one (``--group``).
LISTED = FINDINGS + ("warned-unverifiable",)
_CASE = re.compile(r"seed (\d+) (\S+) \((\S+): ([^)]*)\)")


def _chunk(start, count, timeout, current, conn, targets=None):
    """Run seeds ``start .. start+count-1`` in this (child) process.

    ``current`` holds the seed being read, so that the parent can name it when the process
    dies (a crash in compiled code) or stops making progress; outcomes are sent per case.
    """
    import signal
    logging.getLogger("flexmor").propagate = False
    signal.signal(signal.SIGALRM, _alarm)
    with tempfile.TemporaryDirectory() as tmp, tempfile.TemporaryDirectory() as gen:
        _GEN["dir"] = Path(gen)  # removed with the worker's folders (atexit does not run in a worker)
        _generate(_GEN["dir"])
        for seed in range(start, start + count):
            current.value = seed
            signal.alarm(timeout)
            try:
                cls, text = run_case(seed, Path(tmp), targets)
            except _Timeout:
                cls, text = "crash", f"seed {seed} {target_of(seed, targets).name}: hang: longer than {timeout} s at -"
            finally:
                signal.alarm(0)
            conn.send((seed, cls, text if cls in LISTED else ""))
    conn.send(("done", count, ""))
    conn.close()


def table(counts: dict, markdown: bool = False, targets=None) -> str:
    """The counts per target and class as text (or a Markdown table)."""
    rows = [[t.name] + [counts.get((t.name, c), 0) for c in CLASSES] for t in TARGETS
            if targets is None or t.name in targets]
    rows.append(["total"] + [sum(r[k] for r in rows) for k in range(1, len(CLASSES) + 1)])
    head = ["target", *CLASSES]
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        out += ["| " + " | ".join(f"{x:,}" if isinstance(x, int) else x for x in r) + " |" for r in rows]
    else:
        out = ["".join(f"{h:>20}" for h in head)] + ["".join(f"{x:>20}" for x in r) for r in rows]
    return "\n".join(out)


def groups(texts, markdown: bool = False) -> str:
    """The listed cases (``(class, text)``) grouped by class, target, file and mutations (in the
    order of the mutations' names): count and first seed of each group, largest first."""
    got: dict = {}
    for cls, text in texts:
        m = _CASE.match(text)
        if m is None:  # a crash without a file (a dead worker): by its text
            key, seed = (cls, text.split(":")[0].split()[-1], "-", text.split(": ", 1)[-1][:60]), text.split()[1]
        else:
            seed, name, victim, kinds = m.groups()
            key = (cls, name, victim, "+".join(sorted(kinds.split("+"))))
        got.setdefault(key, []).append(int(seed))
    rows = sorted(got.items(), key=lambda kv: (CLASSES.index(kv[0][0]), -len(kv[1]), kv[0]))
    head = ["class", "target", "file", "mutations", "cases", "first seed"]
    if markdown:
        out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        out += [f"| {c} | {t} | {f} | {k} | {len(s):,} | {min(s)} |" for (c, t, f, k), s in rows]
    else:
        out = [f"{c:<20} {t:<14} {f:<40} {k:<40} {len(s):>6} {min(s):>8}" for (c, t, f, k), s in rows]
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=100_000, help="number of cases")
    ap.add_argument("-j", type=int, default=2, help="worker processes")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--chunk", type=int, default=2000, help="cases per worker process")
    ap.add_argument("--time-limit", type=float, default=None, help="stop after this many seconds (report the count)")
    ap.add_argument("--timeout", type=int, default=20, help="seconds per case before it counts as a hang")
    ap.add_argument("--markdown", action="store_true", help="print the closing table as Markdown")
    ap.add_argument("--group", action="store_true", help="list the silent-different and warned-unverifiable cases "
                                                          "grouped by target, file and mutations")
    ap.add_argument("--targets", default=None, help="comma-separated target names (default: all)")
    a = ap.parse_args(argv)
    import signal as _signal
    from collections import deque
    from multiprocessing.connection import wait

    targets = a.targets.split(",") if a.targets else None
    unknown = set(targets or ()) - {t.name for t in TARGETS}
    if unknown:
        ap.error(f"unknown targets {', '.join(sorted(unknown))}; choose from {', '.join(t.name for t in TARGETS)}")
    t0 = time.perf_counter()
    ctx = mp.get_context("spawn")
    pending = deque((s, min(a.chunk, a.seed + a.n - s)) for s in range(a.seed, a.seed + a.n, a.chunk))
    running = []  # [process, pipe, current seed, first seed, count, (seed, since)]
    counts: dict = {}
    findings, listed = [], []

    def record(seed, cls, text):
        key = (target_of(seed, targets).name, cls)
        counts[key] = counts.get(key, 0) + 1
        if cls in LISTED:
            listed.append((cls, text))
        if cls in FINDINGS:
            findings.append(text)
            if not a.group:
                print(f"{cls}: {text}", flush=True)

    def drain(r):
        while r[1].poll():
            try:
                seed, cls, text = r[1].recv()
            except EOFError:
                return False
            if seed == "done":
                return True
            record(seed, cls, text)
        return False

    def done():
        return sum(counts.values())

    stopped, shown = False, t0
    while pending or running:
        while pending and len(running) < a.j and not stopped:
            start, count = pending.popleft()
            current = ctx.Value("q", start - 1, lock=False)
            rd, wr = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_chunk, args=(start, count, a.timeout, current, wr, targets),
                               daemon=True)
            proc.start()
            wr.close()
            running.append([proc, rd, current, start, count, (start - 1, time.perf_counter())])
        wait([r[0].sentinel for r in running] + [r[1] for r in running], timeout=1.0)
        for r in list(running):
            proc, rd, current, start, count, (seen, since) = r
            if drain(r):
                proc.join()
                running.remove(r)
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
                    record(seed, "crash", f"seed {seed} {target_of(seed, targets).name}: hang: no progress for "
                                          f"{now - since:.0f} s (killed) at -")
                    running.remove(r)
                    if start + count > seed + 1:
                        pending.appendleft((seed + 1, start + count - seed - 1))
                continue
            proc.join()
            drain(r)
            running.remove(r)
            code = proc.exitcode
            how = f"signal {_signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            record(seed, "crash", f"seed {seed} {target_of(seed, targets).name}: the process died ({how}) at -")
            if start + count > seed + 1:
                pending.appendleft((seed + 1, start + count - seed - 1))
        if a.time_limit and time.perf_counter() - t0 > a.time_limit and not stopped:
            stopped = True
            pending.clear()
            for r in running:
                r[0].kill()
                r[0].join()
                drain(r)
            running = []
        if time.perf_counter() - shown > 10:
            shown = time.perf_counter()
            print(f"{done()} cases, {len(findings)} findings, {shown - t0:.0f} s", file=sys.stderr, flush=True)
    print(f"cases {done()}  findings {len(findings)}  time {time.perf_counter() - t0:.1f} s")
    print(table(counts, a.markdown, targets))
    if a.group:
        print(groups(listed, a.markdown))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
