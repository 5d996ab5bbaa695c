"""Regenerate the malformed-input corpus in this folder (``python make_corpus.py``).

Every case is a small file (or a small set of files that belong together, like a CalculiX
``.sti`` + ``.mas`` + ``.dof`` + ``.inp``) built from a tiny valid model of each format, or
from the first lines of a real sample in ``tests/data``, with one defect. ``MANIFEST.tsv``
lists, per case: the main file, the command (``reduce PORT`` or ``info``), and a substring
the one-line error must contain. ``tests/test_bad_corpus.py`` runs them all.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import scipy.io

HERE = Path(__file__).parent
DATA = HERE.parent
CASES: list[tuple[str, str, str]] = []

# --- a tiny valid CalculiX export: 2 nodes x 3 DOFs, K tridiagonal SPD, M diagonal -----------------
# CalculiX writes K and M on one pattern (explicit zeros included), as here
N_CCX = 6
K_UP = [(i, i, 2.0e6) for i in range(1, 7)] + [(i, i + 1, -1.0e6) for i in range(1, 6)]
M_DIAG = [(i, i, 1.0) for i in range(1, 7)]
M_UP = M_DIAG + [(i, i + 1, 0.0) for i in range(1, 6)]
INP = "*HEADING\ntiny\n*NODE, NSET=NALL\n1, 0.0, 0.0, 0.0\n2, 1.0, 0.0, 0.0\n*NSET, NSET=TIP\n2\n"
DOF = "".join(f"{n}.{d}\n" for n in (1, 2) for d in (1, 2, 3))


def _triplets(entries) -> str:
    entries = sorted(entries, key=lambda e: (e[1], e[0]))
    return "".join(f"{r} {c} {v:.13e}\n" for r, c, v in entries)


def ccx(name, expect, *, sti=None, mas=None, dof=None, inp=None, cmd="reduce TIP:y"):
    files = {"sti": _triplets(K_UP) if sti is None else sti, "mas": _triplets(M_UP) if mas is None else mas,
             "dof": DOF if dof is None else dof, "inp": INP if inp is None else inp}
    for ext, text in files.items():
        p = HERE / f"{name}.{ext}"
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
    CASES.append((f"{name}.sti", cmd, expect))


def _ok_k():
    return _triplets(K_UP)


def _swap_line(text, lineno, new):
    lines = text.splitlines(keepends=True)
    lines[lineno - 1] = new
    return "".join(lines)


ccx("ccx_zero_based", "ccx_zero_based.sti:1", sti=_swap_line(_ok_k(), 1, "0 1 2.0e6\n"))
ccx("ccx_negative_index", "ccx_negative_index.sti:2", sti=_swap_line(_ok_k(), 2, "-1 2 -1.0e6\n"))
ccx("ccx_index_beyond", "ccx_index_beyond.sti:3", sti=_swap_line(_ok_k(), 3, "2 7 1.0\n"))
ccx("ccx_nan", "ccx_nan.sti:1", sti=_swap_line(_ok_k(), 1, "1 1 nan\n"))
ccx("ccx_inf", "ccx_inf.mas:4", mas=_swap_line(_triplets(M_UP), 4, "4 4 inf\n"))
ccx("ccx_columns", "ccx_columns.sti:2", sti=_swap_line(_ok_k(), 2, "1 2 -1.0e6 3.0\n"))
ccx("ccx_token", "ccx_token.sti:5", sti=_swap_line(_ok_k(), 5, "3 3 2.0e6x\n"))
ccx("ccx_duplicate", "appears twice", sti=_ok_k() + "2 3 -1.0e6\n")
ccx("ccx_lower_triangle", "below the diagonal", sti=_ok_k() + "3 2 -1.0e6\n")
ccx("ccx_indefinite_mass", "mass matrix diagonal is not positive",
    mas=_triplets([(r, c, -1.0 if r == c == 3 else v) for r, c, v in M_UP]))
ccx("ccx_singular_mass_rows", "equation 6 (node 2, z) (M = 0)",
    sti=_triplets([(r, c, 0.0 if 6 in (r, c) else v) for r, c, v in K_UP]),
    mas=_triplets([(r, c, 0.0 if 6 in (r, c) else v) for r, c, v in M_UP]))
ccx("ccx_dof_unknown_node", "node 9", dof=DOF.replace("2.3", "9.3"))
ccx("ccx_dof_short", "ccx_dof_short.sti", dof="".join(DOF.splitlines(keepends=True)[:5]))
ccx("ccx_empty_nset", "node set 'TIP' is empty", inp=INP.replace("*NSET, NSET=TIP\n2\n", "*NSET, NSET=TIP\n"))
ccx("ccx_node_nan", "non-finite coordinate", inp=INP.replace("1.0, 0.0, 0.0", "nan, 0.0, 0.0"))
ccx("ccx_truncated", "cut off", sti=_ok_k()[:-9])
ccx("ccx_empty", "empty", sti=b"")
_rng = random.Random(11)
ccx("ccx_binary_junk", "binary", sti=bytes(_rng.randrange(256) for _ in range(600)) + _ok_k().encode())
ccx("ccx_huge_index", "ccx_huge_index.sti:1", sti=_swap_line(_ok_k(), 1, "99999999999999999999 1 1.0\n"))
# 3 nodes, one axial spring between nodes 1 and 2: 8 zero-energy modes, a mechanism
ccx("ccx_mechanism", "the model is a mechanism",
    sti=_triplets([(i, i, 1.0e6 if i in (1, 4) else 0.0) for i in range(1, 10)] + [(1, 4, -1.0e6)]),
    mas=_triplets([(i, i, 1.0) for i in range(1, 10)] + [(1, 4, 0.0)]),
    dof="".join(f"{n}.{d}\n" for n in (1, 2, 3) for d in (1, 2, 3)),
    inp=INP.replace("*NSET, NSET=TIP\n2\n", "3, 2.0, 0.0, 0.0\n*NSET, NSET=TIP\n3\n"))

# --- Matrix Market pairs ---------------------------------------------------------------------------


def mm(name, expect, k, m, cmd="info"):
    (HERE / f"{name}_K.mtx").write_text(k)
    (HERE / f"{name}_M.mtx").write_text(m)
    CASES.append((f"{name}_K.mtx", cmd, expect))


SYM = "%%MatrixMarket matrix coordinate real symmetric\n"
K3 = SYM + "3 3 5\n1 1 2.0\n2 1 -1.0\n2 2 2.0\n3 2 -1.0\n3 3 2.0\n"
M3 = SYM + "3 3 3\n1 1 1.0\n2 2 1.0\n3 3 1.0\n"
CASES.append(("asym_K.mtx", "info", "not symmetric"))
mm("mm_size_mismatch", "expected (4, 4)", K3, SYM + "4 4 4\n1 1 1.0\n2 2 1.0\n3 3 1.0\n4 4 1.0\n")
mm("mm_truncated", "mm_truncated_K.mtx", K3.replace("3 3 5", "3 3 9"), M3)
mm("mm_huge_header", "mm_huge_header_K.mtx", K3.replace("3 3 5", "1000000000000 1000000000000 5"), M3)
mm("mm_nan", "mm_nan_K.mtx", K3.replace("2 2 2.0", "2 2 NaN"), M3)
mm("mm_zero_based", "mm_zero_based_K.mtx", K3.replace("1 1 2.0", "0 0 2.0"), M3)
mm("mm_beyond", "mm_beyond_K.mtx", K3.replace("3 3 2.0", "4 3 2.0"), M3)
mm("mm_no_banner", "mm_no_banner_K.mtx", K3.replace(SYM, "% stiffness\n"), M3)
mm("mm_duplicate", "twice", K3.replace("3 3 5", "3 3 6") + "2 2 2.0\n", M3)
mm("mm_mechanism", "mechanism", SYM + "9 9 1\n1 1 1.0\n",
   SYM + "9 9 9\n" + "".join(f"{i} {i} 1.0\n" for i in range(1, 10)))
mm("mm_token", "mm_token_K.mtx", K3.replace("2 1 -1.0", "2 1 -1.0.0"), M3)

# --- Abaqus (.inp + LABELS matrices) ---------------------------------------------------------------
ABQ = ("*Heading\n*Node\n1, 0., 0., 0.\n2, 1., 0., 0.\n*Nset, nset=TIP\n2\n*Step\n"
       "*MATRIX GENERATE, STIFFNESS, MASS\n*MATRIX OUTPUT, STIFFNESS, MASS, FORMAT=LABELS\n*End Step\n")


def _labels(entries):
    lab = [(1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3)]
    return "".join(f"{lab[r - 1][0]},{lab[r - 1][1]}, {lab[c - 1][0]},{lab[c - 1][1]}, {v:.8e}\n"
                   for r, c, v in entries)


def abq(name, expect, stif=None, mass=None, inp=ABQ):
    (HERE / f"{name}.inp").write_text(inp)
    (HERE / f"{name}_STIF1.mtx").write_text(_labels(K_UP) if stif is None else stif)
    (HERE / f"{name}_MASS1.mtx").write_text(_labels(M_DIAG) if mass is None else mass)
    CASES.append((f"{name}.inp", "reduce TIP:y", expect))


abq("abq_unknown_node", "node 7", stif=_labels(K_UP) + "7,1, 7,1, 1.0\n")
abq("abq_direction", "abq_direction_STIF1.mtx", stif=_labels(K_UP).replace("2,3, 2,3", "2,9, 2,9"))
abq("abq_columns", "abq_columns_MASS1.mtx:2", mass=_swap_line(_labels(M_DIAG), 2, "1,2, 1,2\n"))
abq("abq_inf", "abq_inf_STIF1.mtx:1", stif=_swap_line(_labels(K_UP), 1, "1,1, 1,1, -inf\n"))

# --- Nastran ---------------------------------------------------------------------------------------
OP4 = (DATA / "nastran" / "pyyeti_rd_ascii.op4").read_text()
(HERE / "nas_truncated.op4").write_text(OP4[: len(OP4) // 2])
CASES.append(("nas_truncated.op4", "info", "nas_truncated.op4"))
(HERE / "nas_token.op4").write_text(OP4.replace("2.30557969828540100E-01", "2.30557969828540100X-01", 1))
CASES.append(("nas_token.op4", "info", "nas_token.op4"))
PCH = (DATA / "nastran" / "pyyeti_matrix_factory.pch").read_text().splitlines(keepends=True)
(HERE / "nas_junk.pch").write_bytes(bytes(_rng.randrange(256) for _ in range(400)) + "".join(PCH[:30]).encode())
CASES.append(("nas_junk.pch", "info", "nas_junk.pch"))

# --- Ansys, MATLAB, SID, HDF5 ----------------------------------------------------------------------
(HERE / "ansys_junk.full").write_bytes(bytes(_rng.randrange(256) for _ in range(2000)))
CASES.append(("ansys_junk.full", "info", "ansys_junk.full"))
scipy.io.savemat(HERE / "mat_size_mismatch.mat", {"M": np.eye(3), "K": 2 * np.eye(2)})
CASES.append(("mat_size_mismatch.mat", "info", "mat_size_mismatch.mat"))
scipy.io.savemat(HERE / "mat_no_k.mat", {"M": np.eye(3)})
CASES.append(("mat_no_k.mat", "info", "mat_no_k.mat"))
scipy.io.savemat(HERE / "mat_string_k.mat", {"M": np.eye(2), "K": "not a matrix"})
CASES.append(("mat_string_k.mat", "info", "mat_string_k.mat"))
scipy.io.savemat(HERE / "mat_nan.mat", {"M": np.eye(2), "K": np.array([[1.0, np.nan], [np.nan, 1.0]])})
CASES.append(("mat_nan.mat", "info", "mat_nan.mat"))
CASES.append(("text.mat", "info", "text.mat"))
# bench/fuzz.py seed 67581: a token inside the compressed M replaced; scipy's reader alone segfaults
LF10 = (DATA / "mor" / "LF10.mat").read_bytes()
(HERE / "mat_cut_compressed.mat").write_bytes(LF10[:434] + b"0" + LF10[584:])
CASES.append(("mat_cut_compressed.mat", "info", "mat_cut_compressed.mat: damaged MATLAB file: compressed data"))
SID = (DATA / "sid" / "balken1m.SID_FEM").read_text().splitlines(keepends=True)
(HERE / "sid_truncated.SID_FEM").write_text("".join(SID[: len(SID) // 3]))
CASES.append(("sid_truncated.SID_FEM", "info", "sid_truncated.SID_FEM"))
(HERE / "h5_text.h5").write_text("M = [1 0; 0 1]\n")
CASES.append(("h5_text.h5", "info", "h5_text.h5"))

with open(HERE / "MANIFEST.tsv", "w") as f:
    f.write("file\tcommand\texpect\n")
    for row in CASES:
        f.write("\t".join(row) + "\n")
print(len(CASES), "cases")
