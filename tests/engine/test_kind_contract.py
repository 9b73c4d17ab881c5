"""The program-kind contract as xarray's backends have theirs (:mod:`ftsweep.engine.contract`,
:mod:`ftsweep.engine.plugins`): each installed kind is one entry point of group
``ftsweep.kinds`` naming a subclass of ProgramKind; its options and commands come through its
class, which loads no kernel; a broken plug-in is warned about and skipped; a class that
leaves a method or a required attribute unset is refused, saying which."""

from __future__ import annotations

import subprocess
import sys
import warnings
from importlib.metadata import entry_points
from typing import Any

import pytest

from ftsweep import registry
from ftsweep.engine import plugins
from ftsweep.engine.contract import ProgramKind

KINDS = ("ring", "mesh", "spiral", "dpath", "fresnel")


def test_every_installed_kind_is_one_entry_point_naming_its_class():
    points = {p.name: p for p in entry_points(group=plugins.GROUP)}
    assert set(KINDS) <= set(points)
    for name in KINDS:
        cls = points[name].load()
        assert isinstance(cls, type) and issubclass(cls, ProgramKind) and cls.name == name
        assert isinstance(registry.kind(name), cls)
    # no other group of ftsweep's: options and commands come through the kinds' classes
    assert not [g for g in ("ftsweep.options", "ftsweep.commands") if entry_points(group=g)]


def test_the_base_carries_no_kinds_defaults():
    """What a kind must say for itself is unset on the base, and a kind that leaves it unset
    is refused naming it."""
    for name in ProgramKind.REQUIRED:
        assert not hasattr(ProgramKind, name), name

    spiral = type(registry.kind("spiral"))
    own = {m: getattr(spiral, m) for m in (*ProgramKind.REQUIRED, *ProgramKind.__abstractmethods__)}
    complete = type("Complete", (ProgramKind,), own)
    assert isinstance(plugins.checked(complete), complete)
    bare = type("Bare", (ProgramKind,), {k: v for k, v in own.items() if k != "machine"})
    with pytest.raises(plugins.RegistryError, match="required attributes unset: machine"):
        plugins.checked(bare)


def test_a_class_with_a_method_unimplemented_is_refused_naming_it():
    ring = type(registry.kind("ring"))
    own = {
        m: getattr(ring, m) for m in (*ProgramKind.REQUIRED, *ProgramKind.__abstractmethods__) if m != "plan"
    }
    NoPlan = type("NoPlan", (ProgramKind,), own)
    with pytest.raises(plugins.RegistryError, match="abstract methods unimplemented: plan"):
        plugins.checked(NoPlan)
    with pytest.raises(plugins.RegistryError, match="not a subclass of ProgramKind"):
        plugins.checked(object)
    with pytest.raises(plugins.RegistryError, match="names the kind 'ring'"):
        plugins.checked(type(registry.kind("ring")), "other")


class _Point:
    """An entry point as importlib.metadata gives one, whose load fails or gives ``value``."""

    def __init__(self, name: str, value: Any) -> None:
        self.name, self.value, self._value = name, f"broken_plugin:{name}", value

    def load(self) -> Any:
        if isinstance(self._value, Exception):
            raise self._value
        return self._value


def test_a_broken_plugin_is_warned_about_and_skipped(monkeypatch):
    installed = dict(plugins._points())
    broken = {
        "gone": _Point("gone", ImportError("No module named 'broken_plugin'")),
        "notakind": _Point("notakind", 42),
    }
    monkeypatch.setattr(plugins, "_points", lambda: {**installed, **broken})
    plugins._load.cache_clear()
    try:
        with pytest.warns(plugins.BrokenKindWarning) as caught:
            found = plugins.kinds()
        assert set(KINDS) <= set(found) and not {"gone", "notakind"} & set(found)
        said = " ".join(str(w.message) for w in caught)
        assert "'gone' (broken_plugin:gone) skipped: ImportError" in said
        assert "'notakind' (broken_plugin:notakind) skipped: RegistryError: 42 is not a subclass" in said
        with pytest.raises(ValueError, match="unknown program kind 'gone'"), warnings.catch_warnings():
            warnings.simplefilter("ignore", plugins.BrokenKindWarning)
            plugins.kind("gone")
    finally:
        plugins._load.cache_clear()


def test_register_takes_an_instance_checked_as_an_installed_kind_is():
    with pytest.raises(plugins.RegistryError, match="is not a ProgramKind"):
        registry.register(type(registry.kind("ring")))  # the class, not an instance


def test_options_and_commands_come_through_the_kinds_without_loading_a_kernel():
    code = (
        "import sys\n"
        "from ftsweep import registry\n"
        "groups = registry.predict_option_groups()\n"
        "from ftsweep.cli.main import kind_commands\n"
        "print(sorted(kind_commands()), len(groups))\n"
        "print(sorted(m for m in sys.modules if m.startswith('numba') or m.endswith('.kind'))[:3])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    commands, loaded = out.stdout.splitlines()
    assert commands == "['dpath', 'fresnel'] 4"  # ring and mesh share their options' group
    assert loaded == "[]"
