"""The three format registries (FE models, reduced bodies, exports) and ``flexmor info --formats``."""

from __future__ import annotations

import ast
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import flexmor.io
from flexmor.body import ReducedModel
from flexmor.cli import main
from flexmor.errors import OptionError, ReadError
from flexmor.io import BODY_FORMATS, EXPORT_FORMATS, MODEL_FORMATS, Registry

REGISTRIES = {"model": MODEL_FORMATS, "body": BODY_FORMATS, "export": EXPORT_FORMATS}


@pytest.mark.parametrize("kind", sorted(REGISTRIES))
def test_no_suffix_or_name_collision_within_a_registry(kind):
    formats = REGISTRIES[kind].formats().values()
    suffixes = [s for f in formats for s in f.suffixes]
    assert len(suffixes) == len(set(suffixes)), suffixes
    names = [n for f in formats for n in (f.name, *f.aliases)]
    assert len(names) == len(set(names)), names
    for f in formats:  # every suffix leads back to its own format
        for s in f.suffixes:
            assert REGISTRIES[kind].by_path(f"body{s}").name == f.name
            assert REGISTRIES[kind].by_path(f"BODY{s.upper()}").name == f.name


def test_the_registries_hold_the_built_in_formats():
    assert set(MODEL_FORMATS.names()) == {"abaqus", "ansys", "calculix", "matlab", "matrix-market", "nastran", "sid"}
    assert set(BODY_FORMATS.names()) == {"hdf5", "nastran-se"}
    assert set(EXPORT_FORMATS.names()) == {"hdf5", "sid", "exudyn", "mat", "statespace", "fmu", "matrix-market",
                                           "nastran-dmig", "op4", "vtu"}


def test_every_format_is_registered_right_after_import_flexmor_io():
    """A fresh interpreter: the families register themselves when flexmor.io imports them, in a fixed order."""
    code = ("import flexmor.io as io; print({k: [f['name'] for f in v] for k, v in io.describe_formats().items()})")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert eval(out) == {"model": ["calculix", "abaqus", "sid", "matlab", "matrix-market", "ansys", "nastran"],
                         "body": ["hdf5", "nastran-se"],
                         "export": ["hdf5", "sid", "exudyn", "mat", "statespace", "fmu", "matrix-market",
                                    "nastran-dmig", "op4", "vtu"]}


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def _imported_modules(path: Path, module: str) -> set:
    """The modules named by every import statement of ``path`` (module ``module``), functions included."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            base = (f"{base}.{node.module}" if node.module else base) if node.level else node.module
            out.update(f"{base}.{a.name}" if _is_module(f"{base}.{a.name}") else base for a in node.names)
    return out


def test_no_module_of_flexmor_io_imports_the_package_itself():
    """The registries and atomic_write live in leaf modules: a format module never imports flexmor.io's __init__."""
    root = Path(flexmor.io.__file__).parent
    offenders = []
    for path in sorted(root.rglob("*.py")):
        if path == root / "__init__.py":
            continue
        parts = path.relative_to(root.parent.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        if "flexmor.io" in _imported_modules(path, module):
            offenders.append(module)
    assert offenders == []
    assert "flexmor.io" in _imported_modules(root.parent / "cli" / "__init__.py", "flexmor.cli")  # the check sees


def test_registering_a_taken_suffix_or_name_is_refused():
    reg = Registry("test")
    reg.register("one", [".abc", ".x.npz"], print)
    with pytest.raises(ValueError, match=r"suffix \.abc already belongs to 'one'"):
        reg.register("two", [".ABC"], print)
    with pytest.raises(ValueError, match="name one already taken"):
        reg.register("three", [".def"], print, aliases=["one"])
    reg.register("npz", [".npz"], print)
    assert reg.by_path("a.x.npz").name == "one" and reg.by_path("a.npz").name == "npz"  # longest suffix wins
    assert reg.by_path("a.txt") is None


@pytest.mark.parametrize(("registry", "path", "name"), [
    (MODEL_FORMATS, "blockC3D8_STIF1.mtx", "abaqus"),  # claimed by name ahead of the suffix
    (MODEL_FORMATS, "blockC3D8_MASS12.MTX", "abaqus"),
    (MODEL_FORMATS, "rotor_K.mtx", "matrix-market"),
    (MODEL_FORMATS, "LF10.mat", "matlab"),
    (MODEL_FORMATS, "se.op4", "nastran"),
    (BODY_FORMATS, "se.op4", "nastran-se"),  # same suffix, other purpose
    (BODY_FORMATS, "body.H5", "hdf5"),
    (EXPORT_FORMATS, "body.mat", "mat"),
    (EXPORT_FORMATS, "body.ss.mat", "statespace"),
    (EXPORT_FORMATS, "body.ss.npz", "statespace"),
    (EXPORT_FORMATS, "body.exudyn.npz", "exudyn"),
    (EXPORT_FORMATS, "body.SID_FEM", "sid"),
])
def test_a_file_name_chooses_one_format(registry, path, name):
    assert registry.by_path(path).name == name


def test_read_body_refuses_an_unknown_suffix_and_lists_the_body_formats(tmp_path):
    path = tmp_path / "body.xyz"
    path.write_text("not a body")
    with pytest.raises(ReadError) as err:
        flexmor.io.read_body(path)
    msg = str(err.value)
    assert str(path) in msg and "'.xyz'" in msg
    assert ".h5 .hdf5 (hdf5)" in msg and ".op4 .pch (nastran-se)" in msg
    assert ".sti" not in msg  # FE model suffixes are not body formats
    with pytest.raises(OptionError, match="not a known reduced body file type; choose one of: hdf5, nastran-se"):
        flexmor.io.read_body(path, format="calculix")


def test_a_file_of_the_other_reader_registry_is_named(tmp_path):
    red = ReducedModel(M=np.eye(2), K=np.diag([1.0, 4.0]), D=None, B=np.ones((2, 1)), C=np.ones((1, 2)))
    flexmor.io.export(red, tmp_path / "r.h5")  # flexmor's own file, as an export
    assert flexmor.io.read_body(tmp_path / "r.h5").K[1, 1] == 4.0
    with pytest.raises(ReadError, match=r"r\.h5 is a reduced body file: hdf5\); known: .*\.sti \(calculix\)"):
        flexmor.io.read(tmp_path / "r.h5")
    with pytest.raises(ReadError, match=r"m\.sti is an FE model file: calculix\)"):
        flexmor.io.read_body(tmp_path / "m.sti")


def test_info_formats_text(capsys):
    assert main(["info", "--formats"]) == 0
    out = capsys.readouterr().out
    sections = [line for line in out.splitlines() if line and not line.startswith(" ")]
    assert [s.split(" (")[0] for s in sections] == ["FE models", "reduced bodies", "exports"]
    blocks = out.split("\n\n")
    for block, reg in zip(blocks, REGISTRIES.values()):
        rows = [line.split() for line in block.splitlines()[1:]]
        assert [r[0] for r in rows] == reg.names()
        for row, fmt in zip(rows, reg.formats().values()):
            assert set(fmt.suffixes) <= set(row)
    assert "statespace (ss, state-space)  .ss.npz .ss.mat" in out
    assert "<job>_{STIF,MASS,DMPV}<n>.mtx" in out


def test_info_formats_json(capsys):
    assert main(["info", "--formats", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["formats"]) == {"model", "body", "export"}
    for kind, reg in REGISTRIES.items():
        rows = out["formats"][kind]
        assert [r["name"] for r in rows] == reg.names()
        for r in rows:
            assert r["suffixes"] == list(reg.formats()[r["name"]].suffixes) and r["description"]
    calculix = out["formats"]["model"][MODEL_FORMATS.names().index("calculix")]
    assert calculix["suffixes"] == [".sti"] and calculix["claims"] is None
    assert "flexmor_version" in out


def test_a_format_given_for_another_formats_suffix_is_refused_and_a_strange_suffix_named(tmp_path):
    red = ReducedModel(M=np.eye(2), K=np.diag([1.0, 4.0]), D=None, B=np.ones((2, 1)), C=np.ones((1, 2)))
    with pytest.raises(OptionError, match=r"r\.mat: its suffix names mat files, format is hdf5; end the file's "
                                          r"name in \.h5 or \.hdf5"):
        flexmor.io.export(red, tmp_path / "r.mat", "hdf5")
    assert not (tmp_path / "r.mat").exists()
    with pytest.warns(flexmor.FlexmorWarning, match=r"r\.py: written as statespace \(\.ss\.npz or \.ss\.mat\) "
                                                     r"although no export format has the suffix '\.py'"):
        flexmor.io.export(red, tmp_path / "r.py", "ss")
    assert sorted(np.load(tmp_path / "r.py")) == ["A", "Ae", "B", "Be", "C", "D", "E"]  # what the format writes
    # the last part of the format's own suffix: the state space as .mat, Exudyn-less npz names
    assert flexmor.io.export(red, tmp_path / "r.mat", "ss") == "statespace"
    assert flexmor.io.export(red, tmp_path / "r.npz", "statespace") == "statespace"
