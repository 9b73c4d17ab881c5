"""The registry of program kinds, the public face (docs/architecture.md, "The program-kind
contract"): :func:`kind`, :func:`kinds`, :func:`register` and the rest of
:mod:`ftsweep.engine.plugins`, which finds the kinds through the entry points of group
``ftsweep.kinds``, and the vocabularies built from every kind for the layers above them
(sweep axes and options keys, ``predict``'s options). It sits above the kinds: generic code
asks it for a case's kind instead of naming one.
"""

from __future__ import annotations

from typing import Any, Optional

from ftsweep.engine.contract import ProgramKind
from ftsweep.engine.plugins import (
    GROUP,
    BrokenKindWarning,
    RegistryError,
    added,
    kind,
    kinds,
    names,
    noun,
    owners,
    register,
    unregister,
)
from ftsweep.options import flag

__all__ = [
    "GROUP",
    "BrokenKindWarning",
    "RegistryError",
    "added",
    "check_options_keys",
    "check_sweep_axes",
    "flag",
    "kind",
    "kinds",
    "names",
    "noun",
    "owners",
    "predict_option_groups",
    "register",
    "request_from_options",
    "unregister",
]


def check_sweep_axes(spec: Any) -> None:
    """A sweep spec's program axes belong to its kind, and its kind's own rules hold
    (ValueError naming the key)."""
    own = kind(spec.layout)
    for other in kinds().values():
        foreign = [n for n in other.axis_names if n not in own.axis_names and spec.axes.get(n) is not None]
        if foreign:
            raise ValueError(f"axes.{foreign[0]} belongs to {other.sweeps}, not to a {own.name} sweep")
    check_options_keys(spec, own)
    own.check_sweep(spec)


def check_options_keys(spec: Any, own: Optional[ProgramKind] = None) -> None:
    """A sweep spec holds no options key of a kind other than ``own`` (its layout's; None for
    a spec without one): ValueError naming the key and its kind."""
    for other in kinds().values():
        key = other.options_key
        if key is not None and other is not own and spec.options_of(key):
            where = f", not to a {own.name} sweep" if own is not None else ""
            raise ValueError(f"{key} belongs to {other.sweeps} (layout: {other.name}){where}")


def request_from_options(name: str, options: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """The request of kind ``name`` from command-line options (``predict``): options of another
    kind are refused naming their kind, the rest is the kind's own (ValueError naming the
    option); with the notices to show (e.g. a rounded pitch)."""
    own = kind(name)
    # the kinds' option names come from their option groups, which load no kind: the other
    # kinds are loaded only to name the holders of an option given that is not this kind's
    grouped = dict.fromkeys(p.name for params in predict_option_groups().values() for p in params)
    for key in grouped:
        if key not in own.options and options.get(key) is not None:
            holders = [o for o in kinds().values() if key in o.options]
            if not holders:
                continue  # a group's option no kind declares (none today): the kind reads it
            where = " or ".join(f"{o.noun}s (--layout {o.name})" for o in holders)
            raise ValueError(f"{flag(key)} belongs to {where}, not to a {own.noun}")
    return own.from_options(options)


def predict_option_groups() -> dict[str, list[Any]]:
    """Every kind's ``predict`` options (click parameters) by group, titled with the layouts
    they serve: each kind's :meth:`~ftsweep.engine.contract.ProgramKind.click_options`, which
    loads no kernel, so ``predict --help`` loads none. Kinds that share a decorator (ring and
    mesh) share its group, and an option two groups declare is kept in the first."""
    decorators: dict[Any, list[str]] = {}
    for own in kinds().values():
        decorator = own.click_options()
        if decorator is not None:
            decorators.setdefault(decorator, []).append(own.name)
    groups: dict[str, list[Any]] = {}
    seen: set[str] = set()
    for decorator, layouts in decorators.items():
        params = [p for p in _params_of(decorator) if p.name not in seen]
        seen.update(p.name for p in params)
        groups[f"Options of --layout {', '.join(layouts)}"] = params
    return groups


def _params_of(decorator: Any) -> list[Any]:
    """The click parameters a decorator of options adds, in the order ``--help`` shows them."""

    def holder() -> None:  # pragma: no cover - never called: it only collects the options
        pass

    decorator(holder)
    return list(reversed(holder.__dict__.get("__click_params__", [])))
