"""Study files: a whole reduction (model file and its checksum, preparation, ports, band, damping, method,
order, options, judgement) in one TOML file, written by ``flexmor reduce ... --save-study study.toml`` and
reproduced by ``flexmor run study.toml`` or :meth:`flexmor.System.from_study`::

    flexmor = "0.9.0"                     # the version that wrote it
    band = [10.0, 3000.0]                 # Hz; left out: the default band

    [model]
    file = "beam.sti"                     # relative to the study file's folder
    sha256 = "..."                        # of that file: a changed file is refused
    units = "mm-t-s"                      # format, mesh, units, select, preload, material
    select = ["TIP=box:990,0,0,1000,100,100"]

    [model.fingerprint]                   # of the prepared model (companion files and preparation)
    n_dof = 270
    K = "..."
    M = "..."

    [ports]
    inputs = ["TIP:y"]                    # outputs, interfaces

    [damping]
    rayleigh = [0.0, 1e-06]               # or modal_damping = 0.02, or band_rayleigh = 0.01

    [reduce]
    method = "krylov"                     # order, inertia_loads, stress, stress_nodes
    order = 8

    [reduce.options]                      # the method's options
    points = "0,1000j"

    [judge]                               # error, mounted, tol, tol_measure, n_freq, grid_tol, full_frf, cache
    error = true

    [output]
    body = "beam_krylov_8.h5"             # relative to the study file's folder

Every key is checked when the file is read: an unknown one is refused naming it and the closest known key.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from pathlib import Path

from ._version import __version__
from .errors import ModelError, OptionError, ReadError, did_you_mean

__all__ = ["KEYS", "read_study", "write_study", "file_sha256", "check_fingerprint", "study_fingerprint"]

#: The keys of a study file: section -> key -> kind (``text``, ``texts``, ``number``, ``numbers``, ``pair``,
#: ``int``, ``bool``, ``table``); top-level keys under "".
KEYS = {
    "": {"flexmor": "text", "band": "pair"},
    "model": {"file": "text", "sha256": "text", "format": "text", "mesh": "text", "mesh_sha256": "text",
              "units": "text", "select": "texts", "preload": "texts", "material": "numbers", "fingerprint": "table"},
    "ports": {"inputs": "texts", "outputs": "texts", "interfaces": "texts", "moving_loads": "texts",
              "moving_load_tol": "number"},
    "damping": {"rayleigh": "pair", "modal_damping": "number", "band_rayleigh": "number"},
    "reduce": {"method": "text", "order": "int", "inertia_loads": "text", "residual_vectors": "bool",
               "spin_range": "text", "stress": "bool", "stress_nodes": "text", "options": "table"},
    "judge": {"error": "bool", "mounted": "bool", "tol": "number", "tol_measure": "text", "n_freq": "int",
              "grid_tol": "number", "full_frf": "text", "cache": "bool"},
    "output": {"body": "text"},
}

#: The fingerprint entries a study keeps (:func:`flexmor.origin.fingerprint`).
FINGERPRINT = ("n_dof", "n_nodes", "dof_map", "K", "M", "D")


def file_sha256(path) -> str:
    """The SHA-256 of the file ``path`` (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def study_fingerprint(model) -> dict:
    """The entries of :func:`flexmor.origin.fingerprint` a study records (None ones left out)."""
    from .origin import fingerprint

    full = fingerprint(model)
    return {k: full[k] for k in FINGERPRINT if full.get(k) is not None}


def check_fingerprint(study: dict, model, path) -> None:
    """Refuse ``model`` when it is not the one the study file ``path`` was made from (its fingerprint)."""
    from .origin import origin_differences

    recorded = study.get("model", {}).get("fingerprint")
    if not recorded:
        return
    diffs = origin_differences(recorded, model)
    if diffs:
        raise ModelError(f"{path}: the model prepared from {study['model']['file']} is not the one the study was "
                         f"saved with: that one had {'; '.join(diffs)} (a changed companion file of the model, "
                         "or another flexmor?)")


# -- TOML ----------------------------------------------------------------------------------------
def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)  # exact: a float read back is the same float
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise OptionError(f"a study file holds text, numbers, true/false and lists of them; got {v!r} of type "
                      f"{type(v).__name__}")


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() and k.isascii() else _value(k)


def _table(lines: list, name: str, table: dict) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, dict) and v is not None}
    if scalars or not any(isinstance(v, dict) for v in table.values()):
        lines += ["", f"[{name}]"] if name else []
        lines += [f"{_key(k)} = {_value(v)}" for k, v in scalars.items()]
    for k, v in table.items():
        if isinstance(v, dict) and v:
            _table(lines, f"{name}.{_key(k)}" if name else _key(k), v)


def to_toml(study: dict) -> str:
    """The TOML text of ``study`` (its sections in :data:`KEYS` order)."""
    lines = ["# flexmor study: flexmor run FILE (or flexmor.System.from_study(FILE)) reproduces the body"]
    top = {k: study[k] for k in KEYS[""] if study.get(k) is not None}
    lines += [f"{_key(k)} = {_value(v)}" for k, v in top.items()]
    for section in KEYS:
        if section and study.get(section):
            _table(lines, section, study[section])
    return "\n".join(lines) + "\n"


def write_study(path, study: dict) -> None:
    """Write ``study`` to ``path`` (whole or not at all)."""
    from .io.atomic import atomic_write

    text = to_toml({"flexmor": __version__, **study})

    def write(tmp: str) -> None:
        Path(tmp).write_text(text, encoding="utf-8")

    atomic_write(path, write)


def _check_kind(kind: str, value) -> bool:
    number = (int, float)
    if kind == "text":
        return isinstance(value, str)
    if kind == "texts":
        return isinstance(value, list) and all(isinstance(v, str) for v in value)
    if kind == "number":
        return isinstance(value, number) and not isinstance(value, bool)
    if kind in ("numbers", "pair"):
        return (isinstance(value, list) and all(isinstance(v, number) and not isinstance(v, bool) for v in value)
                and (kind == "numbers" or len(value) == 2))
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "bool":
        return isinstance(value, bool)
    return isinstance(value, dict)


_KIND_WORDS = {"text": "a text", "texts": "a list of texts", "number": "a number", "numbers": "a list of numbers",
               "pair": "two numbers [A, B]", "int": "an integer", "bool": "true or false", "table": "a table"}


def read_study(path) -> dict:
    """The study of the file ``path``, checked: every key known and of its kind, the model file (and
    mesh file) where the study says, unchanged since the study was saved (SHA-256). Paths of the
    model, mesh and body are returned relative to the current folder.

    Raises
    ------
    ReadError
        The file cannot be read or is not TOML (with the line).
    OptionError
        An unknown key (naming the closest known one), a value of the wrong kind, no model or method.
    ModelError
        The model file changed since the study was saved.
    """
    path = Path(path)
    try:
        study = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ReadError(path, f"cannot read the study file: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ReadError(path, f"not a study file (TOML): {exc}") from None
    for section, value in study.items():
        if section in KEYS[""]:
            continue
        if section not in KEYS:
            raise _unknown(path, section, [*KEYS[""], *(s for s in KEYS if s)])
        if not isinstance(value, dict):
            raise OptionError(f"{path}: [{section}] must be a table of keys")
        for key in value:
            if key not in KEYS[section]:
                raise _unknown(path, f"{section}.{key}", [f"{section}.{k}" for k in KEYS[section]])
    for section, keys in KEYS.items():
        table = study if not section else study.get(section, {})
        for key, kind in keys.items():
            if key in table and not _check_kind(kind, table[key]):
                where = f"{section}.{key}" if section else key
                raise OptionError(f"{path}: {where} must be {_KIND_WORDS[kind]}, got {table[key]!r}")
    model = study.get("model", {})
    if "file" not in model or "method" not in study.get("reduce", {}):
        missing = "model.file" if "file" not in model else "reduce.method"
        raise OptionError(f"{path}: a study needs {missing}")
    folder = path.parent
    for key, sha in (("file", "sha256"), ("mesh", "mesh_sha256")):
        if key not in model:
            continue
        target = folder / model[key]
        if not target.exists():
            raise ReadError(path, f"the {'model' if key == 'file' else 'mesh'} file {target} of the study does "
                            "not exist")
        model[key] = str(target)
        if sha in model and file_sha256(target) != model[sha]:
            raise ModelError(f"{path}: the {'model' if key == 'file' else 'mesh'} file {target} changed since the "
                             f"study was saved (its SHA-256 is not the one recorded); save the study again")
    if "body" in study.get("output", {}):
        study["output"]["body"] = str(folder / study["output"]["body"])
    return study


def _unknown(path, key: str, known: list) -> OptionError:
    near = did_you_mean(key, known).strip()
    return OptionError(f"{path}: unknown key {key!r} in the study file" + (f" ({near})" if near else "")
                       + f"; known: {', '.join(known)}")


def relative_to(path, folder) -> str:
    """``path`` relative to ``folder`` when the two share a folder below the file system's root (a study
    moved with its model keeps finding it), else absolute; with forward slashes."""
    import os

    target, base = Path(path).resolve(), Path(folder).resolve()
    try:
        common = Path(os.path.commonpath([target, base]))
    except ValueError:  # another drive
        return target.as_posix()
    if common == Path(common.anchor):
        return target.as_posix()
    return Path(os.path.relpath(target, base)).as_posix()
