"""The ``ftsweep`` command line: the group, its error handling and the ``catalogs`` command;
the other commands live in ``cli_*`` modules by family and are registered here."""

from __future__ import annotations

import os
import sys
from typing import Any

import click

from ftsweep import __version__, catalogs
from ftsweep.cli_common import MESSAGE_LIMIT, USER_ERRORS, echo_json, one_line


class _Group(click.Group):
    """Turns every error into a one-line message and a non-zero exit (no traceback); set
    FTSWEEP_DEBUG=1 to see the traceback of an unexpected one."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            raise click.UsageError(one_line(exc.format_message()), exc.ctx) from None
        except click.ClickException as exc:
            raise click.ClickException(one_line(exc.format_message())) from None
        except (click.exceptions.Exit, click.Abort, KeyboardInterrupt, SystemExit):
            raise
        except BrokenPipeError:
            # the reader went away (e.g. `| head`): stop quietly, as other command-line tools do
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            sys.exit(1)
        except Exception as exc:
            if os.environ.get("FTSWEEP_DEBUG"):
                raise
            known = isinstance(exc, USER_ERRORS)
            hint = "" if known else " (an unexpected error: set FTSWEEP_DEBUG=1 for the traceback)"
            text = str(exc) if known and str(exc) else f"{type(exc).__name__}: {exc}"
            raise click.ClickException(one_line(text, MESSAGE_LIMIT - len(hint)) + hint) from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="ftsweep")
def main() -> None:
    """Control-point layouts for fast-tool-servo (FTS) diamond turning.

    An FTS controller moves the tool by bilinear interpolation in a table of control
    points (rings in polar coordinates or a Cartesian mesh). ftsweep predicts the form
    error a layout leaves on the machined part, including tool-nose compensation and the
    tool-arc envelope (the model is in the README, section "The model").

    \b
    Units: lengths µm, errors nm, angles degrees, feed µm/rev.
    Catalogs (surfaces, machines, cutting conditions) are YAML files in catalogs/ or in
    the folder named by $FTSWEEP_CATALOGS; `ftsweep catalogs` lists them.
    """
    from ftsweep import allocator

    allocator.tune()  # large batch temporaries reused, not page-faulted afresh (see the module)


@main.command("catalogs")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def list_catalogs(as_json: bool) -> None:
    """List the surfaces, machines, cutting conditions and sweeps the catalogs define.

    Descriptions are printed whole, wrapped to the terminal. With --json, one object maps
    each kind to its entries (every field, units in the field names) and the sweep names.
    """
    import shutil
    import textwrap

    from ftsweep.sweep import sweep_dir

    kinds = ("surfaces", "machines", "cutting")
    found = {kind: catalogs.entries(kind) for kind in kinds}
    sweeps = sorted(p.stem for p in sweep_dir().glob("*.yaml"))
    if as_json:
        data: dict[str, Any] = {
            kind: {name: spec.model_dump(mode="json") for name, spec in entries.items()}
            for kind, entries in found.items()
        }
        data["sweeps"] = sweeps
        data["catalog_dir"] = str(catalogs.catalog_dir())
        echo_json(data)
        return
    width = max(40, min(shutil.get_terminal_size((100, 24)).columns, 120))
    for kind in kinds:
        click.echo(f"{kind} ({catalogs.catalog_dir() / (kind + '.yaml')}):")
        for name, spec in found[kind].items():
            extra = f" [{spec.family}, {spec.layout} layout]" if kind == "surfaces" else ""
            desc = " ".join(spec.description.split())
            click.echo(
                textwrap.fill(
                    f"{name}{extra}: {desc}",
                    width=width,
                    initial_indent="  ",
                    subsequent_indent="      ",
                    break_on_hyphens=False,  # keep "Noll-indexed", "off-axis" whole
                )
            )
    click.echo(f"sweeps ({sweep_dir()}):")
    for name in sweeps:
        click.echo(f"  {name}")


def _register() -> None:
    """Add every command to the group (each lives in the module of its family)."""
    from ftsweep import cli_cubes, cli_predict, cli_programs, cli_tools

    for command in (
        cli_predict.predict,
        cli_cubes.sweep,
        cli_cubes.select,
        cli_cubes.export,
        cli_cubes.verify,
        cli_tools.optimize,
        cli_cubes.report,
        cli_tools.estimate,
        cli_tools.bench,
        cli_cubes.compare,
        cli_programs.dpath_command,
        cli_programs.fresnel_command,
    ):
        main.add_command(command)


_register()


if __name__ == "__main__":  # pragma: no cover
    main()
