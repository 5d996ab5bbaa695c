"""Numbers a user can trust: the body's model is checked, each body is judged with its own
damping, the error tables carry the measures an engineer reads, orders are honest, and SIGTERM
always ends a run with 143 and no output."""

import dataclasses
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp
from helpers import CLAMPED, FREE, run, run_json

import flexmor
from flexmor.analysis.frequency import MEASURES, at_antiresonance, error_measures
from flexmor.cli import main
from flexmor.errors import ModelError
from flexmor.io import read_body
from flexmor.origin import check_origin, fingerprint

SRC = Path(flexmor.__file__).parent


@pytest.fixture(scope="module")
def bodies(tmp_path_factory):
    """A damped and an undamped modal body of the clamped beam (TIP:y -> TIP:y)."""
    d = tmp_path_factory.mktemp("bodies")
    common = ["--method", "modal", "--order", "8", "--input", "TIP:y", "--output", "TIP:y"]
    assert main(["reduce", CLAMPED, *common, "--rayleigh", "0:1e-5", "-o", str(d / "damped.h5"), "--json"]) == 0
    assert main(["reduce", CLAMPED, *common, "-o", str(d / "undamped.h5"), "--json"]) == 0
    return d


def test_compare_judges_each_body_with_its_own_damping(capsys, bodies):
    """The issue's reproducer: the second (undamped) body got band_error 1.7e15 (6e16 here)."""
    out = run_json(capsys, "compare", CLAMPED, bodies / "damped.h5", bodies / "undamped.h5")
    damped, undamped = out["results"]
    assert damped["damping"] == {"type": "rayleigh", "alpha": 0.0, "beta": 1e-5}
    assert undamped["damping"] == {"type": "none"}
    # the same numbers as when each is compared alone (as at reduce time)
    alone = run_json(capsys, "compare", CLAMPED, bodies / "undamped.h5")["results"][0]
    assert undamped["band_error"] == pytest.approx(alone["band_error"], rel=1e-6)
    assert 1e-9 < damped["band_error"] < 1e-6 and 1e-9 < undamped["band_error"] < 1e-6
    assert len(out["grids"]) == 2
    code, text, _ = run(capsys, "compare", CLAMPED, bodies / "damped.h5", bodies / "undamped.h5")
    assert code == 0 and "each body's own damping" in text and "Rayleigh alpha 0 1/s, beta 1e-05 s" in text


def test_compare_refuses_damping_flags_that_contradict_a_body(capsys, bodies):
    code, _, err = run(capsys, "compare", CLAMPED, bodies / "damped.h5", bodies / "undamped.h5",
                       "--rayleigh", "0:1e-5")
    assert code == 2
    assert "body undamped.h5 was reduced with damping none" in err and "--rayleigh" in err
    # the body's own damping given again is no conflict
    out = run_json(capsys, "compare", CLAMPED, bodies / "damped.h5", "--rayleigh", "0:1e-5")
    assert out["results"][0]["band_error"] < 1e-6


def test_a_body_is_refused_with_another_model(capsys, bodies, tmp_path):
    code, _, err = run(capsys, "compare", FREE, bodies / "damped.h5")
    assert code == 2
    assert "body damped.h5 was reduced from a model with 270 DOF, this model has 297" in err
    assert "beam8_clamped_mat.sti" in err
    code, _, err = run(capsys, "report", FREE, bodies / "damped.h5", "-o", tmp_path / "r.html")
    assert code == 2 and "body damped.h5" in err and not (tmp_path / "r.html").exists()
    code, _, err = run(capsys, "export", bodies / "damped.h5", "--format", "sid", "--model", FREE,
                       "-o", tmp_path / "b.SID_FEM")
    assert code == 2 and "body damped.h5" in err and "270 DOF" in err


def test_fingerprint_names_the_matrix_that_differs(clamped, bodies):
    red = read_body(bodies / "undamped.h5")
    assert fingerprint(clamped).items() <= red.origin.items() and red.origin["n_dof"] == 270
    assert red.origin["couplings"] == [] and red.origin["interfaces"] == []
    check_origin(red, clamped, "undamped.h5")  # the same model passes
    stiffer = dataclasses.replace(clamped, K=clamped.K * 1.01)
    with pytest.raises(ModelError, match=r"undamped\.h5 was reduced from a model with a different stiffness "
                                         r"matrix K \(the body's model"):
        check_origin(red, stiffer, "undamped.h5")
    # the hash sees the matrix, not the storage order of its entries
    coo = clamped.M.tocoo()
    p = np.random.default_rng(0).permutation(coo.nnz)
    unsorted = sp.csr_matrix((coo.data[p], (coo.row[p], coo.col[p])), shape=coo.shape)
    unsorted.has_sorted_indices = False
    assert fingerprint(dataclasses.replace(clamped, M=unsorted))["M"] == red.origin["M"]


def test_a_body_without_fingerprint_is_compared_with_a_warning(capsys, caplog, bodies, tmp_path):
    old = tmp_path / "old.h5"
    old.write_bytes((bodies / "undamped.h5").read_bytes())
    with h5py.File(old, "r+") as h:
        del h.attrs["origin"]
    assert read_body(old).origin == {}
    out = run_json(capsys, "compare", CLAMPED, old)  # the command line shows warnings in its log
    assert any("old.h5 records no fingerprint" in r.getMessage() for r in caplog.records)
    assert out["results"][0]["band_error"] < 1e-6


def test_report_refuses_bodies_with_different_damping(capsys, bodies, tmp_path):
    code, _, err = run(capsys, "report", CLAMPED, bodies / "damped.h5", bodies / "undamped.h5",
                       "-o", tmp_path / "r.html")
    assert code == 2 and "undamped.h5 (none)" in err and "flexmor compare" in err


def test_info_on_a_body(capsys, bodies):
    code, text, err = run(capsys, "info", bodies / "damped.h5")
    assert code == 0, err
    for piece in ("modal, order 8", "inputs      TIP:y", "Rayleigh alpha 0 1/s, beta 1e-05 s",
                  "freqs [Hz]  100.05 100.05 608.56", "band 1-1000 Hz: band_error 9.6", "rms_rel_error",
                  "beam8_clamped_mat.sti): 270 DOF, 99 nodes", "fingerprint K "):
        assert piece in text
    out = run_json(capsys, "info", bodies / "damped.h5")
    assert out["method"] == "modal" and out["order"] == 8 and out["order_requested"] == 8
    assert out["inputs"] == ["TIP:y"] and out["damping"]["beta"] == 1e-5
    assert out["model"]["n_dof"] == 270 and out["model"]["source"].endswith("beam8_clamped_mat.sti")
    np.testing.assert_allclose(out["frequencies_hz"][:3], [100.046, 100.046, 608.565], rtol=1e-4)
    assert out["errors"]["band_error"] == pytest.approx(9.6e-8, rel=0.05)


def test_error_measures_an_engineer_reads(capsys, bodies):
    out = run_json(capsys, "compare", CLAMPED, bodies / "undamped.h5")["results"][0]
    assert out["rms_rel_error_pct"] == pytest.approx(100 * math.sqrt(out["band_error"]), rel=1e-12)
    assert out["band_rms_error"] == pytest.approx(math.sqrt(out["band_error"]), rel=1e-12)
    assert 0 < out["hinf_error"] < 1e-4 < out["max_rel_error"]
    # the tip's anti-resonance of the clamped beam lies near 429 Hz: max_rel_error sits there
    assert out["max_rel_error_hz"] == pytest.approx(429, rel=0.02) and out["max_rel_error_at_antiresonance"]
    assert any("anti-resonance near 429" in n for n in out["notes"])
    code, text, _ = run(capsys, "compare", CLAMPED, bodies / "undamped.h5")
    assert "rms %" in text and "hinf_error" in text and "429.2 Hz AR" in text
    assert "rms % = 100 sqrt(band_error)" in text


def test_antiresonance_and_resonance_notes_on_an_analytic_curve():
    f = np.geomspace(10, 1000, 401)
    h = np.abs(1 / (1 - (f / 300) ** 2 + 0.01j * f / 300)) * np.abs(1 - (f / 100) ** 2 + 0.001j)
    H = h[:, None, None].astype(complex)
    Hr = H * (1 + 1e-3)
    Hr[np.argmin(h)] += 1e-2 * h.max()  # a large relative error at the anti-resonance (100 Hz)
    m = error_measures(f, H, Hr, resonances=[300.0])
    assert m["max_rel_error_hz"] == pytest.approx(100, rel=0.02) and m["max_rel_error_at_antiresonance"]
    assert not at_antiresonance(f, H, int(np.argmin(np.abs(f - 300))))
    assert not at_antiresonance(f, H, f.size - 1)  # a band end is not a local minimum
    assert set(MEASURES) == {"band_error", "rms_rel_error_pct", "hinf_error", "max_rel_error"}


@pytest.mark.slow
def test_undamped_resonance_dominated_error_suggests_damping(capsys, tmp_path):
    out = run_json(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--interface", "TIP", "--order", "33",
                   "--input", "TIP:y", "-o", tmp_path / "cb.h5")
    assert out["resonance_share"] > 0.5
    assert any(n.startswith("undamped model") and "--rayleigh" in n for n in out["notes"])


@pytest.mark.slow
def test_craig_bampton_tol_chooses_the_fixed_interface_modes(capsys, tmp_path):
    out = run_json(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--interface", "TIP", "--tol", "1e-4",
                   "--input", "TIP:y", "--output", "TIP:y", "-o", tmp_path / "cb.h5")
    assert 27 < out["order"] < 60 and out["band_error"] <= 1e-4 and out["tol_reached"]
    assert out["order_requested"] is None and out["order_note"] is None
    tried = {int(k): v for k, v in out["info"]["tol_search"]["orders_tried"].items()}
    assert min(tried) > 27 and all(v > 1e-4 for k, v in tried.items() if k < out["order"])  # the smallest
    f = out["info"]["fixed_interface_hz"]  # order meeting it: one less was tried, or would cut a pair
    assert out["order"] - 1 in tried or abs(f[-1] - f[-2]) <= 1e-6 * f[-1]
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--interface", "TIP",
                       "--input", "TIP:y", "-o", tmp_path / "x.h5")
    assert code == 2 and "--order (at least the 27 interface DOFs" in err and "got" not in err
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "guyan", "--interface", "TIP", "--tol", "1e-4",
                       "--input", "TIP:y", "-o", tmp_path / "g.h5")
    assert code == 2 and "--tol does not apply to guyan" in err


@pytest.mark.slow
def test_tol_measure(capsys, tmp_path):
    out = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--tol", "1", "--tol-measure",
                   "rms_rel_error_pct", "--input", "TIP:y", "--rayleigh", "0:1e-5", "-o", tmp_path / "m.h5")
    assert out["tol_measure"] == "rms_rel_error_pct" and out["rms_rel_error_pct"] <= 1
    assert out["info"]["tol_search"]["measure"] == "rms_rel_error_pct"
    tried = {int(k): v for k, v in out["info"]["tol_search"]["orders_tried"].items()}
    assert tried[out["order"]] == pytest.approx(out["rms_rel_error_pct"], rel=1e-9)
    with pytest.raises(SystemExit):
        main(["reduce", "--help"])
    text = re.sub(r"(\w)- (\w)", r"\1-\2", " ".join(capsys.readouterr().out.split()))  # a name wrapped at its hyphen
    assert "--tol-measure" in text and "rms_rel_error_pct: 100·sqrt(band_error)" in text
    for method in ("modal", "craig-bampton", "krylov", "fw-sobt", "two-step", "cms-krylov", "pod"):
        assert method in text.split("--tol TOL target error")[1].split("not guyan")[0].split("Methods:")[1]


@pytest.mark.slow
def test_orders_that_differ_from_the_request_say_why(capsys, tmp_path):
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "craig-bampton", "--interface", "TIP", "--order", "400",
                       "--input", "TIP:y", "--no-error", "-o", tmp_path / "cb.h5")  # more than the model's DOF
    assert code == 2 and "--order 400 exceeds the number of DOF 270 of the model" in err
    assert not (tmp_path / "cb.h5").exists()
    out = run_json(capsys, "reduce", CLAMPED, "--method", "fw-sobt", "--order", "8", "--input", "TIP:y",
                   "--output", "TIP:y", "--inertia-loads", "off", "--no-error", "-o", tmp_path / "fw.h5")  # one port
    assert out["order"] < 8 and out["order_requested"] == 8
    assert f"order {out['order']} instead of 8" in out["order_note"] and "Hankel singular values" in out["order_note"]
    code, text, _ = run(capsys, "info", tmp_path / "fw.h5")
    assert "(8 requested)" in text and "Hankel singular values" in text
    out = run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "8", "--input", "TIP:y", "--no-error",
                   "-o", tmp_path / "m.h5")
    assert out["order"] == 8 and out["order_note"] is None


# -- signals -------------------------------------------------------------------------------------
class _DiesInDestructor:
    """Sends SIGTERM to its own process from ``__del__``: the handler's exception is then lost
    ("Exception ignored in ... __del__"), as with pypardiso's solver object."""

    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs at one of these bytecodes, inside __del__
            pass


def test_sigterm_lost_in_a_destructor_still_ends_with_143_and_no_output(capsys, monkeypatch, tmp_path):
    import flexmor.study as wf

    orig = wf.reduce_and_judge

    def reduce_and_judge(*a, **k):
        out = orig(*a, **k)
        obj = _DiesInDestructor()
        del obj  # SIGTERM arrives inside __del__; the exception is swallowed there
        return out

    monkeypatch.setattr(wf, "reduce_and_judge", reduce_and_judge)
    body = tmp_path / "body.h5"
    code, _, err = run(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "6", "--input", "TIP:y",
                       "--no-error", "-o", body)
    assert code == 143 and err.strip().splitlines()[-1] == "flexmor: terminated"
    assert "Exception ignored" not in err and not body.exists() and list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handler is removed again


@pytest.mark.slow
def _catches_sigterm(pid: int) -> bool:
    """Whether process ``pid`` has a handler for SIGTERM (Linux: the SigCgt mask of /proc/PID/status)."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:  # ended
        return False
    mask = next(int(line.split()[1], 16) for line in text.splitlines() if line.startswith("SigCgt:"))
    return bool(mask >> (signal.SIGTERM - 1) & 1)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the signal mask from /proc (Linux)")
def test_sigterm_at_any_moment_gives_143_and_no_output(tmp_path):
    """``kill -TERM`` at several moments of a run: 143 and no file, or 0 and the file. The moments count
    from the instant flexmor's handler is in place (seen in /proc, so that neither the interpreter's start
    nor the machine's speed decides what is tested): at once (inside the run: 143), and later, up to past
    the run's end. Before the handler the default action ends the process (-15, no file either). Once
    the outcome is decided SIGTERM stays blocked: a signal during the interpreter's shutdown (once seen
    as -15 with the finished file) no longer changes it."""
    env = dict(os.environ, PYTHONPATH=str(SRC.parent), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    codes = []
    for k, delay in enumerate((0.0, 0.05, 0.2, 0.5, 1.0, 2.0, 4.0)):
        folder = tmp_path / f"run{k}"
        folder.mkdir()
        out = folder / "body.h5"
        # fw-sobt with one factorization per quadrature node: a run of about a second to interrupt
        proc = subprocess.Popen([sys.executable, "-m", "flexmor", "reduce", CLAMPED, "--method", "fw-sobt",
                                 "--order", "4", "--input", "TIP:y", "--output", "TIP:y", "--no-cache",
                                 "--solves", "direct", "-o", str(out)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, text=True)
        start = time.monotonic()
        while not _catches_sigterm(proc.pid) and proc.poll() is None and time.monotonic() - start < 60:
            time.sleep(0.002)
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        codes.append(proc.returncode)
        assert proc.returncode in (0, 143), (delay, err)
        if proc.returncode != 0:
            assert list(folder.iterdir()) == [], err
            assert "Exception ignored" not in err and "Traceback" not in err
        else:
            assert out.exists()
    assert codes[0] == 143, codes


def test_info_on_a_model_shows_mass_centre_box_and_selections(capsys):
    out = run_json(capsys, "info", FREE, "--select", "END=box:0.9,0,0,1,1,1")
    np.testing.assert_allclose(out["mass"], [78.5] * 3, rtol=1e-12)  # 7850 kg/m3 * 1 x 0.1 x 0.1 m
    np.testing.assert_allclose(out["center_of_mass"], [0.5, 0.05, 0.05], atol=1e-12)
    assert out["bounding_box"] == [[0.0, 0.0, 0.0], [1.0, 0.1, 0.1]]
    assert len(out["selections"]["END"]) == 18 and out["node_sets"]["END"] == 18
    # the clamped export carries no mass at its 9 clamped nodes (27 DOFs removed)
    assert run_json(capsys, "info", CLAMPED)["mass"][0] == pytest.approx(73.2667, rel=1e-5)
    code, text, _ = run(capsys, "info", FREE, "--select", "S=sphere:1,0,0,0.1")
    assert code == 0 and "selected  S: 3 nodes: 10 33 77 (a sphere selects the nodes on its surface" in text
    assert "mass      78.5 " in text and "c.o.m.    (0.5, 0.05, 0.05)" in text


@pytest.mark.slow
def test_a_coupled_body_matches_its_model_once_coupled_again(capsys, tmp_path):
    body = tmp_path / "c.h5"
    made = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--interface", "TIP@rbe2", "--order", "10",
                    "--input", "TIP@rbe2:y", "--rayleigh", "0:1e-6", "-o", body)
    origin = run_json(capsys, "info", body)["model"]
    assert origin["n_dof"] == 297 - 27 + 6 and origin["couplings"] == ["TIP@rbe2"]
    out = run_json(capsys, "compare", FREE, body)["results"][0]  # the RBE2 is applied again: same fingerprint
    assert out["band_error"] == pytest.approx(made["band_error"], rel=1e-6)


def test_modal_damping_is_checked_by_its_ratio(capsys, tmp_path):
    body = tmp_path / "md.h5"
    run_json(capsys, "reduce", CLAMPED, "--method", "modal", "--order", "8", "--input", "TIP:y",
             "--modal-damping", "0.02", "-o", body)
    out = run_json(capsys, "compare", CLAMPED, body, "--modal-damping", "0.02", "--band", "10:2000")
    assert out["results"][0]["damping"]["type"] == "modal" and out["results"][0]["damping"]["zeta"] == 0.02
    code, _, err = run(capsys, "compare", CLAMPED, body, "--modal-damping", "0.03")
    assert code == 2 and "modal damping 0.02 in every mode" in err and "modal damping 0.03" in err


def test_files_written_by_other_threads_are_not_the_runs(tmp_path):
    """``flexmor ui`` runs commands in worker threads: SIGTERM of the server must not delete their files."""
    import threading

    from flexmor.cli import _Run

    run = _Run()
    with run.guard(tmp_path / "mine.h5"):
        pass

    def job():
        with run.guard(tmp_path / "job.h5"):
            pass

    worker = threading.Thread(target=job)
    worker.start()
    worker.join()
    assert run.written == [tmp_path / "mine.h5"]
    run.terminated = True  # after SIGTERM the run's own thread commits nothing more
    with pytest.raises(BaseException) as exc:
        with run.guard(tmp_path / "late.h5"):
            pass
    assert type(exc.value).__name__ == "_Terminated" and run.written == [tmp_path / "mine.h5"]


@pytest.mark.slow
def test_craig_bampton_tol_on_a_free_body_starts_above_the_interface(capsys, tmp_path):
    """A free body's Craig-Bampton basis keeps n_b = 27 columns (inertia-relief attachment modes)."""
    out = run_json(capsys, "reduce", FREE, "--method", "craig-bampton", "--interface", "TIP", "--tol", "1e-3",
                   "--input", "TIP:y", "--rayleigh", "0:1e-6", "-o", tmp_path / "cb.h5")
    tried = {int(k): v for k, v in out["info"]["tol_search"]["orders_tried"].items()}
    assert min(tried) > 27 and out["tol_reached"] and out["band_error"] <= 1e-3
    assert all(v > 1e-3 for k, v in tried.items() if k < out["order"])
    f = out["info"]["fixed_interface_hz"]  # one order less was tried, or would cut a pair
    assert out["order"] - 1 in tried or abs(f[-1] - f[-2]) <= 1e-6 * f[-1]


def test_every_method_takes_a_coupling_interface(capsys, tmp_path):
    """--interface SET@rbe2 is a joint of the model (coupled, judged held there, its inertia loads in the basis),
    as README says and System(interfaces=...) does; krylov refused it ('does not take --interface'). A plain node
    set stays a Craig-Bampton option."""
    out = run_json(capsys, "reduce", FREE, "--method", "krylov", "--order", "12", "--interface", "FIX@rbe2",
                   "--input", "TIP:y", "--rayleigh", "5:2e-6", "--band", "10:3000", "-o", tmp_path / "k.h5")
    assert out["mounted"] is not None and out["info"]["masters"][0]["name"] == "FIX@RBE2"
    assert out["info"]["n_inertia_loads"] == 6
    code, _, err = run(capsys, "reduce", FREE, "--method", "krylov", "--order", "12", "--interface", "FIX",
                       "--input", "TIP:y", "-o", tmp_path / "x.h5")
    assert code == 2 and "does not take --interface (as a node set; a coupling --interface SET@rbe2" in err
