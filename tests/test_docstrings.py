"""Every public name is documented: the names of ``flexmor.__all__`` (with the home the package
docstring gives them), and every public function and class of a module's ``__all__`` with its
public methods and properties."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

import scipy.sparse as sp

import flexmor
from flexmor.linalg.distributed import PartitionedMatrix

#: Classes that stand in for another library's class and keep its interface: their attributes that
#: an instance of that class has too are documented there.
MIRRORS = {PartitionedMatrix: sp.csr_matrix}


def public_modules():
    """The modules of the package whose dotted path has no ``_``-prefixed part."""
    names = [m.name for m in pkgutil.walk_packages(flexmor.__path__, "flexmor.")
             if not any(p.startswith("_") for p in m.name.split(".")[1:])]
    return [flexmor] + [importlib.import_module(n) for n in sorted(names)]


def public_objects():
    """``(where, object)`` of every function and class in the ``__all__`` of a public module, once."""
    seen, out = set(), []
    for mod in public_modules():
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name)
            if (inspect.isclass(obj) or inspect.isfunction(obj)) and id(obj) not in seen:
                seen.add(id(obj))
                out.append((f"{mod.__name__}.{name}", obj))
    return out


def _own_doc(cls, name: str, value) -> str | None:
    """The docstring of ``cls.name`` (a method, property, classmethod or staticmethod), or of the
    method it overrides in a base class outside flexmor (a standard protocol) or in the class it mirrors."""
    f = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
    doc = inspect.cleandoc(f.__doc__ or "")
    if doc:
        return doc
    for base in cls.__mro__[1:]:
        if not base.__module__.startswith("flexmor") and name in vars(base) and inspect.getdoc(getattr(base, name)):
            return inspect.getdoc(getattr(base, name))
    if cls in MIRRORS and hasattr(MIRRORS[cls]((1, 1)), name):
        return f"{MIRRORS[cls].__name__}.{name}"
    return None


def missing_docstrings() -> list[str]:
    missing = []
    for where, obj in public_objects():
        if not inspect.getdoc(obj) or (inspect.isclass(obj) and obj.__doc__ is None):
            missing.append(where)
        if not inspect.isclass(obj):
            continue
        for name, value in vars(obj).items():
            if name.startswith("_"):
                continue
            if not (inspect.isfunction(value) or isinstance(value, (property, classmethod, staticmethod))):
                continue  # fields and constants: the class docstring's Attributes
            if not _own_doc(obj, name, value):
                missing.append(f"{where}.{name}")
    return missing


def test_every_public_name_and_attribute_has_a_docstring():
    assert missing_docstrings() == []


def test_the_walk_finds_a_missing_docstring(monkeypatch):
    from flexmor.ports import Ports

    prop = vars(Ports)["n_inputs"]
    monkeypatch.setattr(Ports, "n_inputs", property(lambda self: prop.fget(self), doc=""))
    assert missing_docstrings() == ["flexmor.ports.Ports.n_inputs"]


def _homes() -> dict[str, str]:
    """``{name: home}`` from the literal block of the package docstring."""
    block = flexmor.__doc__.split("its home, the module to read (and import) it from::", 1)[1]
    homes, pending = {}, []
    for line in block.split("\n\n", 2)[1].splitlines():
        m = re.match(r"^\s+(.*?)\s{2,}(flexmor[\w.]*)\s*$", line)
        names = (m.group(1) if m else line).replace(",", " ").split()
        pending += names
        if m:
            homes.update({n: m.group(2) for n in pending})
            pending = []
    assert not pending, pending
    return homes


def test_package_docstring_gives_every_name_its_home():
    homes = _homes()
    assert sorted(homes) == sorted(flexmor.__all__)
    for name, home in homes.items():
        obj, mod = getattr(flexmor, name), importlib.import_module(home)
        if inspect.ismodule(obj):
            assert obj is mod, name
        else:
            assert getattr(mod, name) is obj, (name, home)
            assert name == "__version__" or name in getattr(mod, "__all__", ()), (name, home)
