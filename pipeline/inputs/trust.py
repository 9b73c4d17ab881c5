"""The trust model (docs/guide.md "Trust"): catalogs and plug-ins are code the user chose to run;
exported files and cubes are data. Entries a cube or sidecar recorded are validated here, and
a plug-in surface they name is accepted only if the local catalog declares it, before
anything is imported.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ftsweep.inputs.case_entries import Entries
from ftsweep.inputs.catalogs import (
    CatalogError,
    Cutting,
    Machine,
    catalog_dir,
    entries,
    error_text,
    short_repr,
    surface_spec,
)


def specs_from_entries(
    surface: dict[str, Any],
    machine: dict[str, Any],
    cutting: dict[str, Any],
    trust_plugins: bool = False,
    folder: Path | None = None,
) -> Entries:
    """(surface, machine, cutting) specs validated from recorded entries (a cube's or a
    header sidecar's provenance), so results are re-derived from what was used, not from the
    catalogs as they are now.

    Recorded entries are data (docs/guide.md "Trust"): a plug-in surface they name is accepted only
    if a plug-in entry of the local catalog (``folder``, default :func:`catalog_dir`) names
    the same function with the same parameters, unless ``trust_plugins``; otherwise
    :class:`CatalogError`, before anything is imported."""
    from pydantic import TypeAdapter

    try:
        spec = TypeAdapter(surface_spec()).validate_python(surface)
    except ValidationError as exc:
        raise CatalogError(f"the recorded surface entry is invalid ({one_error(exc)})") from None
    if spec.family == "plugin" and not trust_plugins:
        check_plugin_trusted(spec, folder)
    return Entries(spec, Machine.model_validate(machine), Cutting.model_validate(cutting))


def check_plugin_trusted(spec: Any, folder: Path | None = None) -> None:
    """Refuse a recorded plug-in surface that no plug-in entry of the local catalog declares
    with the same function and parameters (the code a file names is never imported)."""
    folder = folder or catalog_dir()
    wanted = spec.params.model_dump(mode="json")
    try:
        local = entries("surfaces", folder)
    except CatalogError:
        local = {}
    for entry_spec in local.values():
        if entry_spec.family == "plugin" and entry_spec.params.model_dump(mode="json") == wanted:
            return
    raise CatalogError(
        f"the file names plug-in {short_repr(wanted['function'])}, which no plug-in entry of the local "
        f"catalog ({folder / 'surfaces.yaml'}) declares with these parameters; ftsweep does not run code "
        "named by a file it reads: add the entry to your catalog, or give --trust-plugins if you trust "
        "this file"
    )


def one_error(exc: ValidationError) -> str:
    """The first error of a validation, as ``location: message`` (no pydantic URL)."""
    errors = exc.errors()
    if not errors:
        return str(exc).splitlines()[0]
    e = errors[0]
    loc = ".".join(str(p) for p in e["loc"])
    return f"{loc}: {error_text(e)}" if loc else error_text(e)


def first_difference(got: Any, want: Any, where: str) -> str | None:
    """The first field where recorded entries ``got`` differ from the local catalog's
    ``want`` (JSON-like), as ``where.key[i]: recorded X, the local catalog has Y``; None
    when they are equal."""
    if isinstance(got, dict) and isinstance(want, dict):
        for key in sorted(set(got) | set(want)):
            found = first_difference(got.get(key), want.get(key), f"{where}.{key}")
            if found:
                return found
        return None
    if isinstance(got, list) and isinstance(want, list) and len(got) == len(want):
        for i, (a, b) in enumerate(zip(got, want, strict=True)):
            found = first_difference(a, b, f"{where}[{i}]")
            if found:
                return found
        return None
    if got != want:
        return f"{where}: recorded {json.dumps(got)[:80]}, the local catalog has {json.dumps(want)[:80]}"
    return None
