"""CalculiX .frd result files: nodes, MODAL steps with DISP blocks (ASCII long/short, binary), broken files.

The frd files are written here in the layout of the CalculiX GraphiX manual's result format,
with the clamped beam's nodes, CalculiX's own eigenfrequencies and the beam's mode shapes.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from flexmor.errors import ReadError
from flexmor.io.calculix import compare_modes, modes, read_frd
from flexmor.linalg import eigenmodes

N_MODES = 6


def _shapes(model):
    lam, phi = eigenmodes(model.K, model.M, N_MODES)
    ids = np.sort(model.node_ids)
    U = np.zeros((N_MODES, ids.size, 3))
    pos = {int(n): i for i, n in enumerate(ids)}
    for e, (g, d) in enumerate(model.dofs):
        U[:, pos[int(g)], d - 1] = phi[e]
    return ids, U


def _write(path, model, freqs, *, fmt=1, binary=False, perturb=None, gk=False):
    ids, U = _shapes(model)
    if perturb is not None:
        U = perturb(U)
    xyz = model.node_xyz(ids)
    w = 10 if fmt == 1 else 5
    out = bytearray()

    def line(s):
        out.extend((s + "\n").encode())

    line("    1Cbeam")
    line("    1UUSER        flexmor test")
    line(f"    2C{'':18s}{ids.size:12d}{'':37s}{3 if binary else fmt:1d}")
    if binary:
        for n, x in zip(ids, xyz):
            out.extend(struct.pack("<i3d", n, *x))
    else:
        for n, x in zip(ids, xyz):
            line(f" -1{n:{w}d}" + "".join(f"{v:12.5E}" for v in x))
        line(" -3")
    line(f"    3C{'':18s}{1:12d}{'':37s}{2 if binary else fmt:1d}")
    if binary:
        out.extend(struct.pack("<4i8i", 1, 1, 0, 1, *ids[:8]))
    else:
        line(f" -1{1:{w}d}{1:5d}{0:5d}{1:5d}")
        line(" -2" + "".join(f"{n:{w}d}" for n in ids[:8]))
        line(" -3")
    line("    1PSTEP                         1           1           1")
    for i, f in enumerate(freqs):
        line(f"    1PMODE{i + 1:12d}")
        line(f"    1PGM  {1.0:12.6E}")
        if gk:
            line(f"    1PGK  {(2 * np.pi * f) ** 2:16.9E}")
        line(f"  100CL{101 + i:5d}{f:12.5E}{ids.size:12d}{'':20s}{2:2d}{i + 1:5d}{'MODAL':10s}"
             f"{2 if binary else fmt:2d}")
        line(" -4  DISP        4    1")
        for k in range(3):
            line(f" -5  D{k + 1}          1    2{k + 1:5d}    0")
        line(" -5  ALL         1    2    0    0    1ALL")
        if binary:
            for n, u in zip(ids, U[i]):
                out.extend(struct.pack("<i3f", n, *u))
        else:
            for n, u in zip(ids, U[i]):
                line(f" -1{n:{w}d}" + "".join(f"{v:12.5E}" for v in u))
            line(" -3")
    line(" 9999")
    path.write_bytes(bytes(out))
    return ids, xyz, U


@pytest.mark.slow
@pytest.mark.parametrize("fmt, binary", [(1, False), (0, False), (1, True)])
def test_frd_modes_match_the_model(tmp_path, clamped, clamped_ref, fmt, binary):
    p = tmp_path / "beam.frd"
    ids, xyz, U = _write(p, clamped, clamped_ref[:N_MODES], fmt=fmt, binary=binary)
    res = read_frd(p)
    np.testing.assert_array_equal(res.node_ids, ids)
    np.testing.assert_allclose(res.xyz, xyz, atol=1e-6)
    f, nodes, shapes = modes(res)
    np.testing.assert_allclose(f, clamped_ref[:N_MODES], rtol=1e-5)
    np.testing.assert_allclose(shapes, U, atol=1e-5 * abs(U).max())
    assert res.blocks[0]["components"] == ["D1", "D2", "D3"] and res.blocks[1]["params"]["MODE"] == "2"
    cmp = compare_modes(clamped, res)
    assert max(cmp["rel_diff"]) < 1e-5
    exact = np.array(cmp["model_frequencies_hz"])
    _write(p, clamped, exact, fmt=fmt, binary=binary, gk=True)  # 1PGK carries 10 digits, the 100CL value 6
    np.testing.assert_allclose(modes(read_frd(p))[0], exact, rtol=1e-9)
    assert abs(read_frd(p).blocks[0]["value"] / exact[0] - 1) > 1e-9
    assert min(cmp["mac"]) > 0.9999  # also for the pairs of equal frequency


def test_compare_detects_wrong_directions(tmp_path, clamped, clamped_ref):
    p = tmp_path / "swap.frd"
    _write(p, clamped, clamped_ref[:N_MODES], perturb=lambda U: U[..., [1, 0, 2]])  # x and y swapped
    cmp = compare_modes(clamped, read_frd(p))
    assert min(cmp["mac"]) < 0.5


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace(" -3\n    3C", "    3C", 1), "expected ' -3' after the 99 nodes"),
    (lambda t: t.replace("E-0", "X-0", 1), "non-numeric"),
    (lambda t: t[: t.index("  100CL  102")], "no end record 9999"),
    (lambda t: t[: t.index("  100CL  102") - 150], "file ends inside a block"),
    (lambda t: t.replace(" -4  DISP", " -7  DISP", 1), "expected the ' -4' record"),
    (lambda t: "    5Cjunk\n" + t, "unknown frd record"),
])
def test_broken_frd(tmp_path, clamped, clamped_ref, edit, words):
    p = tmp_path / "bad.frd"
    _write(p, clamped, clamped_ref[:2])
    p.write_text(edit(p.read_text()))
    with pytest.raises(ReadError, match=words) as exc:
        read_frd(p)
    assert "bad.frd" in str(exc.value)


def test_broken_binary_frd(tmp_path, clamped, clamped_ref):
    p = tmp_path / "bin.frd"
    _write(p, clamped, clamped_ref[:2], binary=True)
    raw = p.read_bytes()
    p.write_bytes(raw[:200])
    with pytest.raises(ReadError, match="truncated"):
        read_frd(p)


def test_info_reference(tmp_path, clamped, clamped_ref, capsys):
    from helpers import CLAMPED

    from flexmor.cli import main

    p = tmp_path / "job.frd"
    _write(p, clamped, clamped_ref[:N_MODES])
    assert main(["info", CLAMPED, "--reference", str(p), "--json"]) == 0
    import json

    ref = json.loads(capsys.readouterr().out)["reference"]
    assert len(ref["mac"]) == N_MODES and max(ref["rel_diff"]) < 1e-5 and min(ref["mac"]) > 0.9999
    p.write_text(p.read_text().replace(" 9999\n", ""))
    assert main(["info", CLAMPED, "--reference", str(p)]) == 2
    assert "job.frd" in capsys.readouterr().err


def test_the_frd_of_a_free_body_pairs_one_to_one(free, clamped):
    """CalculiX's own .frd of the free beam: its six rigid-body modes pair with the model's and lie in their span
    (MAC 1; they were measured against the modes near each one's frequency, 0.28-0.97), and against the clamped
    model nothing is paired twice and the missing rigid-body modes are said."""
    from helpers import CCX

    from flexmor.errors import FlexmorWarning

    res = read_frd(CCX / "beam8_free_mat.frd")
    cmp = compare_modes(free, res)
    assert cmp["model_modes"] == list(range(1, len(cmp["model_modes"]) + 1)) and cmp["notes"] == []
    assert min(cmp["mac"]) > 1 - 1e-6 and cmp["rel_diff"][:6] == [None] * 6
    assert max(d for d in cmp["rel_diff"] if d is not None) < 1e-6
    with pytest.warns(FlexmorWarning, match="the reference has 6 rigid-body modes, the model 0"):
        cmp = compare_modes(clamped, res)
    paired = [j for j in cmp["model_modes"] if j is not None]
    assert cmp["model_modes"][:6] == [None] * 6 and cmp["mac"][:6] == [None] * 6
    assert paired == sorted(set(paired))  # one-to-one, in order
