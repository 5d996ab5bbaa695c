"""The streamed, vectorized text readers give bit for bit the matrices of a plain line-by-line parse
(``float()`` on each number), over many chunks; a corrupted line deep in a file is named by its number."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import flexmor.io
import flexmor.io._sparse as sparse_mod
import flexmor.io._text as text_mod
from flexmor.errors import ReadError
from flexmor.io._fastparse import fast_triplets
from flexmor.io.nastran import dmig_fast

N_NODES = 60


@pytest.fixture(autouse=True)
def small_chunks(monkeypatch):
    """Chunks and blocks of a few kB, so that a small file crosses many of them."""
    monkeypatch.setattr(text_mod, "_CHUNK", 1 << 12)
    monkeypatch.setattr(dmig_fast, "_CHUNK", 1 << 12)
    monkeypatch.setattr(sparse_mod, "_BLOCK", 97)


def _matrices():
    """Symmetric K and M on 3 DOFs per node, values from 1e-14 to 1e9 (the exact paths and strtod), explicit zeros."""
    rng = np.random.default_rng(11)
    n = 3 * N_NODES
    A = sp.random(n, n, density=0.08, random_state=3, data_rvs=lambda k: rng.standard_normal(k))
    A.data *= 10.0 ** rng.integers(-14, 9, A.nnz)
    A = A + A.T
    K = (A + sp.diags(np.abs(A).sum(axis=1).A1 + 1.0)).tocoo()
    K.data[((K.row + K.col) % 13 == 0) & (K.row != K.col)] = 0.0  # explicit zeros (symmetric) stay stored
    M = sp.diags(rng.uniform(1.0, 2.0, n) * 1e-9).tocsr() + sp.eye(n, k=3) * 1e-12 + sp.eye(n, k=-3) * 1e-12
    return K.tocsr(), M.tocsr()


def _one_pattern(K, M):
    """K and M on the union of their patterns (zeros stored), as CalculiX writes them."""
    P = (abs(K).astype(bool).astype(float) + abs(M).astype(bool).astype(float)).tocoo()
    Kd, Md = K.toarray(), M.toarray()
    return [sp.csr_matrix((A[P.row, P.col], (P.row, P.col)), shape=K.shape) for A in (Kd, Md)]


def _triplet_lines(A, fmt, base=1):
    A = sp.triu(A).tocsc().tocoo() if fmt.endswith("u") else A.tocoo()
    form = "{i} {j} {v:.13e}\n" if fmt.startswith("ccx") else "{i},{j}, {v:.15e}\n"
    return "".join(form.format(i=i + base, j=j + base, v=v) for i, j, v in zip(A.row.tolist(), A.col.tolist(),
                                                                          A.data.tolist()))


def _nodes_deck(ids):
    return "*NODE\n" + "".join(f"{i}, {i * 0.5}, 0.0, 0.0\n" for i in ids.tolist())


def _write(fmt, d):
    """The matrix files of ``fmt`` in ``d``; returns (file to read, the matrix files by role)."""
    K, M = _matrices()
    ids = np.arange(1, N_NODES + 1)
    if fmt == "calculix":
        K, M = _one_pattern(K, M)
        (d / "job.sti").write_text(_triplet_lines(K, "ccxu"))
        (d / "job.mas").write_text(_triplet_lines(M, "ccxu"))
        (d / "job.dof").write_text("".join(f"{i}.{k}\n" for i in ids for k in (1, 2, 3)))
        (d / "job.inp").write_text(_nodes_deck(ids))
        return d / "job.sti", {"K": d / "job.sti", "M": d / "job.mas"}
    if fmt == "abaqus":
        (d / "job_STIF1.mtx").write_text(_triplet_lines(K, "abq"))
        (d / "job_MASS1.mtx").write_text(_triplet_lines(M, "abq"))
        (d / "job.inp").write_text(_nodes_deck(ids) + "*ELEMENT, TYPE=C3D8, ELSET=E\n")
        return d / "job.inp", {"K": d / "job_STIF1.mtx", "M": d / "job_MASS1.mtx"}
    if fmt == "matrix-market":
        for name, A in (("K", K), ("M", M)):
            L = sp.tril(A).tocoo()
            (d / f"job_{name}.mtx").write_text(f"%%MatrixMarket matrix coordinate real symmetric\n% exported\n"
                                               f"{A.shape[0]} {A.shape[0]} {L.nnz}\n" + _triplet_lines(L, "ccx"))
        return d / "job_K.mtx", {"K": d / "job_K.mtx", "M": d / "job_M.mtx"}
    lines = []
    for name, A in (("KAAX", K), ("MAAX", M)):
        U = sp.triu(A).tocsc()
        lines.append(f"DMIG    {name:<8}{0:8d}{6:8d}{2:8d}{0:8d}")
        for j in range(U.shape[1]):
            lines.append(f"DMIG*   {name:<16}{j // 3 + 1:>16}{j % 3 + 1:>16}")
            lines += [f"*       {i // 3 + 1:>16}{i % 3 + 1:>16}{v:16.9E}".replace("E", "D")
                      for i, v in zip(U.indices[U.indptr[j]:U.indptr[j + 1]].tolist(),
                                      U.data[U.indptr[j]:U.indptr[j + 1]].tolist())]
    (d / "job.pch").write_text("\n".join(lines) + "\n")
    return d / "job.pch", {"K": d / "job.pch", "M": d / "job.pch"}


def _reference(fmt, path, name):
    """The matrix of a file, parsed line by line with ``float()``; one triangle completed."""
    n = 3 * N_NODES
    entries = []
    if fmt == "nastran":
        col = None
        for line in path.read_text().splitlines():
            if line.startswith("DMIG*   " + name):
                col = (int(line[24:40]) - 1) * 3 + int(line[40:56]) - 1
            elif line.startswith("DMIG"):
                col = None
            elif line.startswith("*") and col is not None:
                entries.append(((int(line[8:24]) - 1) * 3 + int(line[24:40]) - 1, col,
                                float(line[40:56].replace("D", "E"))))
    else:
        for line in path.read_text().splitlines()[3 if fmt == "matrix-market" else 0:]:
            i, j, v = line.replace(",", " ").split()
            entries.append((int(i) - 1, int(j) - 1, float(v)))
    r, c, v = (np.array(x) for x in zip(*entries))
    A = np.zeros((n, n))
    A[r, c] = v
    if fmt != "abaqus":  # one triangle stored
        A[c, r] = v
    return A


@pytest.mark.parametrize("fmt", ["calculix", "abaqus", "matrix-market", "nastran"])
def test_bit_identical_to_a_line_by_line_parse(tmp_path, fmt):
    main, files = _write(fmt, tmp_path)
    model = flexmor.io.read(main)
    names = {"K": "KAAX", "M": "MAAX"} if fmt == "nastran" else {"K": "", "M": ""}
    for role in ("K", "M"):
        A = getattr(model, role)
        ref = _reference(fmt, files[role], names[role])
        np.testing.assert_array_equal(A.toarray(), ref)  # bit for bit
        assert A.has_canonical_format
    K, M = _matrices()
    written = _one_pattern(K, M) if fmt == "calculix" else (K, M)
    for A, W in zip((model.K, model.M), written):  # the file's explicit zeros (CalculiX: K's pattern in M) are
        assert W.nnz >= A.nnz == np.count_nonzero(W.data)  # not stored
    if fmt == "calculix":
        assert written[1].nnz > model.M.nnz


def _corrupt(path, frac=0.9, junk=None):
    lines = path.read_text().splitlines(keepends=True)
    k = int(len(lines) * frac)
    while lines[k].startswith("DMIG"):
        k += 1
    if junk is None:
        junk = lines[k].replace("e", "x", 1).replace("D", "x", 1)
    lines[k] = junk
    path.write_text("".join(lines))
    return k + 1


@pytest.mark.parametrize("fmt", ["calculix", "abaqus", "matrix-market", "nastran"])
def test_corrupted_line_deep_in_the_file_is_named(tmp_path, fmt):
    main, files = _write(fmt, tmp_path)
    lineno = _corrupt(files["M"] if fmt != "nastran" else files["K"])
    with pytest.raises(ReadError) as exc:
        flexmor.io.read(main)
    assert exc.value.line == lineno


@pytest.mark.parametrize("fmt", ["calculix", "abaqus", "matrix-market", "nastran"])
def test_duplicate_entry_deep_in_the_file_is_named(tmp_path, fmt):
    main, files = _write(fmt, tmp_path)
    path = files["K"]
    lines = path.read_text().splitlines(keepends=True)
    k = int(len(lines) * 0.8)
    while not lines[k - 1][:1].isdigit() and not lines[k - 1].startswith("* "):
        k += 1
    lines.insert(k, lines[k - 1])  # the entry above, once more
    if fmt == "matrix-market":
        n, _, nnz = lines[2].split()
        lines[2] = f"{n} {n} {int(nnz) + 1}\n"
    path.write_text("".join(lines))
    with pytest.raises(ReadError, match="twice") as exc:
        flexmor.io.read(main)
    assert exc.value.line == k + 1


def test_exact_halfway_and_far_powers_read_as_strtod():
    """Decimal midpoints between doubles (17 digits) and powers of ten beyond 1e22 round as ``strtod`` does."""
    rng = np.random.default_rng(5)
    mids = (rng.integers(10**16, 2**54, 3000) | 1).tolist()  # odd: halfway between two doubles
    for exps in (np.zeros(3000, int), rng.integers(-60, 60, 3000)):
        text = "".join(f"1 2 {s[0]}.{s[1:]}e{e - 16:+03d}\n" for s, e in zip(map(str, mids), exps.tolist()))
        got = fast_triplets(np.frombuffer(text.encode(), dtype=np.uint8))
        ref = np.array([float(x.split()[2]) for x in text.splitlines()])
        np.testing.assert_array_equal(got[2], ref)


def test_shorter_lines_after_the_first_chunk(tmp_path):
    """Arrays sized by the first chunk's shortest line grow when later lines are shorter."""
    lines = [f"{100000 + i} {100000 + i} {i:.13e}" for i in range(400)] + [f"{i} {i} {i:.13e}" for i in range(1, 2000)]
    path = tmp_path / "m.txt"
    path.write_text("\n".join(lines) + "\n")
    rows, cols, vals = text_mod.parse_triplets(path)
    assert rows.size == 2399 and rows[-1] == 1998 and vals[-1] == 1999.0 and rows[0] == 99999
