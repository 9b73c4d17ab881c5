"""Which machines read which programs, and a cube's case planned for another machine than the
one it was swept for (``export --machine``): the same case, its program planned for that
machine's controller, capacity, units and limits, and predicted there."""

from __future__ import annotations

from typing import Any

from ftsweep.errors import ExportError
from ftsweep.inputs.case_entries import Entries

# what a case's prediction on another machine replaces in the selection the cube gave
_PREDICTED = ("n_points", "pv_nm", "rms_nm", "pv_interp_nm", "pv_inner_nm", "pv_outer_nm")


def for_machine(
    case: Any, specs: Entries, chosen: dict[str, Any], machine: str, dialect: str | None
) -> tuple[Any, Entries, dict[str, Any], dict[str, Any]]:
    """The cube's chosen ``case`` planned for ``machine`` of the local catalog instead of the
    machine it was swept for: its controller, capacity, units and limits; predicted there
    (the full simulation, model §1–§6), so the file states the P-V it will cut on that machine.
    Refused, naming why, where the machine cannot run it: its controller does not read
    ``dialect`` or the kind's programs, the program exceeds its capacity, or its W motion is
    infeasible there. Returns the case, its specs, the selection with the new prediction and
    what the sidecar records of the change."""
    from ftsweep.engine.case import CaseError
    from ftsweep.inputs import catalogs
    from ftsweep.simulate import run_case

    try:
        spec = catalogs.entry("machines", machine)
    except catalogs.CatalogError as exc:
        raise ExportError(f"--machine: {exc}") from None
    moved = case.model_copy(update={"machine": machine})
    specs = specs._replace(machine=spec)
    if dialect is not None:
        check_dialect(machine, spec, dialect)
    _check_kind_reads(moved, spec)
    try:
        record = run_case(moved, specs=specs)
    except (CaseError, ValueError) as exc:
        raise ExportError(f"the case cannot be planned for machine '{machine}': {exc}") from None
    if record.get("feasible", 1) != 1:
        raise ExportError(
            f"on machine '{machine}' the case's W motion is infeasible ({record.get('infeasible_reason')}); "
            "nothing exported"
        )
    before = {"machine": case.machine, "pv_nm": chosen["pv_nm"], "n_points": chosen["n_points"]}
    moved_chosen = {**chosen, **{k: float(record[k]) for k in _PREDICTED if k in record}}
    moved_chosen["n_points"] = int(record["n_points"])
    moved_chosen["rule"] = f"{chosen['rule']}; planned for machine {machine}"
    return moved, specs, moved_chosen, {"machine": machine, "cube": before}


def _check_kind_reads(case: Any, machine: Any) -> None:
    """Refuse a machine whose controller cannot take the case's kind of program: a table
    (ring, mesh) is a header for a table-driven FTS controller, which a G-code or PMAC
    controller does not read, and a path program needs a controller that reads programs."""
    from ftsweep.exports.files import ProgramError
    from ftsweep.exports.nc import adapter_of

    if machine.controller is None:
        return  # a machine that declares no controller takes ftsweep's own formats
    try:
        adapter_of(case.layout.kind)
    except ProgramError:
        raise ExportError(
            f"machine '{case.machine}' has a controller that reads {machine.controller.dialect} programs, "
            f"not a {case.layout.kind} table: sweep the part as a path program (layout: spiral) on it, "
            "or export for a machine that reads tables: "
            f"{', '.join(_table_machines()) or 'none in the catalog'}"
        ) from None


def _table_machines() -> list[str]:
    """The catalog's machines that declare no program controller (their FTS reads tables)."""
    from ftsweep.inputs import catalogs

    return sorted(m for m, e in catalogs.entries("machines").items() if e.controller is None)


def dialect_for(name: str, machine: Any, dialect: str | None, kind: str) -> str:
    """The dialect a file of a ``kind`` case for machine ``name`` is written in: ``dialect`` as
    asked (checked by :func:`check_dialect`; a kind without programs in controllers' dialects,
    a table, refused first, saying what would give one), else its controller's
    (:func:`ftsweep.exports.nc.default_dialect`); ftsweep's text lines only where the machine
    interpolates linearly."""
    from ftsweep.exports import nc

    if dialect not in (None, "text"):
        nc.adapter_of(kind)
    dialect = dialect or nc.default_dialect(machine)
    check_dialect(name, machine, dialect)
    if dialect == "text" and machine.interpolation != "linear":
        raise ExportError(
            f"machine '{name}' interpolates {machine.interpolation}; ftsweep's text programs are "
            f"linear: export --dialect {machine.controller.dialect}"
        )
    return dialect


def check_dialect(name: str, machine: Any, dialect: str) -> None:
    """Refuse a dialect that the machine's controller does not read (a file is written in the
    conventions of the machine it is exported for: a Moore's G-code on a LinuxCNC machine
    would carry F in the other's units), naming the machines whose controllers read it. A
    machine that declares no controller takes any linear dialect in that dialect's defaults."""
    from ftsweep.exports.dialects import machines_reading

    own = machine.controller.dialect if machine.controller is not None else None
    if own is None or dialect in ("text", own):
        return
    readers = machines_reading(dialect)
    raise ExportError(
        f"machine '{name}' has a {own} controller, which does not read {dialect}: export --dialect {own} "
        f"(or text), or export for a machine whose controller reads {dialect} "
        f"({', '.join(f'--machine {m}' for m in readers) or 'none in the catalog'})"
    )
