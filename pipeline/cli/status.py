"""``ftsweep status``: how a cube stands (cases by status with their reasons, its writer, its
growth, its last run), for a person or, with --json, for a scheduler."""

from __future__ import annotations

from typing import Any

import click

from ftsweep.cli.common import CUBE, STORAGE_OPTIONS, cube_place, echo_json, one_line


@click.command()
@click.argument("cube_path", metavar="CUBE", type=CUBE)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
@STORAGE_OPTIONS
def status(cube_path: str, as_json: bool, storage_options: tuple[str, ...]) -> None:
    """How a sweep's cube stands (a folder or a URL), without writing to it.

    Its spec, its cases done, pending, failed, refused and pruned (cases the workers logged
    but the driver has not merged yet count as they will be), the reasons of the failed and
    refused ones grouped, who holds its lock or lease and until when, how it grew, and the
    last run. Exit status 0 when every case that can be computed is (select's answer cannot
    change), 1 when some are pending, failed or pruned.

    \b
    Examples:
      ftsweep status outputs/sinewave-ring.zarr
      ftsweep status s3://optics/sinewave-ring.zarr --json
    """
    from ftsweep.store.cube import CubeError
    from ftsweep.tools.status import cube_status

    try:
        found = cube_status(cube_place(cube_path, storage_options))
    except CubeError as exc:
        raise click.ClickException(str(exc)) from None
    if as_json:
        echo_json(found)
    else:
        for line in status_lines(found):
            click.echo(line)
    raise SystemExit(0 if found["complete"] else 1)


def status_lines(s: dict[str, Any]) -> list[str]:
    """The status as lines of text."""
    c = s["counts"]
    axes = ", ".join(f"{name} ×{len(values)}" for name, values in s["axes"].items())
    lines = [
        f"cube         {s['cube']}",
        f"sweep        {s['sweep']}: {s['surface']}, {s['layout']} layouts on {s['machine']}; {axes}",
        f"cases        {s['cases']}: {c['done']} done, {c['pending']} pending, {c['failed']} failed, "
        f"{c['refused']} refused, {c['pruned']} pruned"
        + ("" if s["complete"] else " (incomplete: a choice from it could change)"),
    ]
    for name, groups in s["reasons"].items():
        for group in groups:
            lines.append(f"{name:<12s} {group['count']} case(s), e.g. {one_line(group['example'], 200)}")
    lines.append(f"writer       {_writer_text(s['writer'])}")
    for entry in s.get("unreadable", []):
        lines.append(f"unreadable   {entry}: its cases count as pending; the next sweep rewrites it")
    for step in s["grown"]:
        lines.append(f"grown        {step.get('at')}: {step.get('added')}")
    run = s["last_run"]
    if run is not None:
        done = ", ".join(f"{n} {name}" for name, n in run["cases"].items() if n)
        lines.append(f"last run     {run['run_id']} (started {run['started']}): {done or 'nothing recorded'}")
    lines.append(f"created      {s['created']} by ftsweep {s['ftsweep_version']}")
    return lines


def _writer_text(w: Any) -> str:
    if w is None:
        return "none (nobody writes it)"
    who = f"pid {w.get('pid')} on {w.get('host')} since {w.get('started')} ({str(w.get('command', ''))[:80]})"
    if w["kind"] == "lease":
        state = "expired" if w.get("expired") else "held"
        return f"lease {state} until {w.get('lease_until')}: {who}"
    alive = {True: "running", False: "gone (the next run takes the lock over)", None: "on another host"}
    return f"lock file: {who}, {alive[w.get('alive')]}"
