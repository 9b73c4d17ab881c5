"""The ``ftsweep`` command line: the group, its error handling and the ``catalogs`` command;
the other commands live in ``ftsweep.cli``'s modules by family, and the kinds' own commands
in their subpackages, each given by its kind (:meth:`ftsweep.engine.contract.ProgramKind.commands`)."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import os
import sys
import warnings
from typing import Any, Optional

import click

from ftsweep.cli.common import MESSAGE_LIMIT, USER_ERRORS, echo_json, one_line
from ftsweep.version import __version__

# every command but `catalogs`: its module and function, imported only when the command runs or
# shows its own help, so that `ftsweep --help` need not load numba, xarray or zarr; the group's
# help reads their one-line summaries from the modules' source
COMMANDS = {
    "sweep": ("ftsweep.cli.sweep", "sweep"),
    "status": ("ftsweep.cli.status", "status"),
    "select": ("ftsweep.cli.cubes", "select"),
    "export": ("ftsweep.cli.cubes", "export"),
    "verify": ("ftsweep.cli.cubes", "verify"),
    "predict": ("ftsweep.cli.predict", "predict"),
    "report": ("ftsweep.cli.cubes", "report"),
    "compare": ("ftsweep.cli.cubes", "compare"),
    "estimate": ("ftsweep.cli.tools", "estimate"),
    "optimize": ("ftsweep.cli.tools", "optimize"),
    "measure": ("ftsweep.cli.measure", "measure"),
    "correct": ("ftsweep.cli.correct", "correct"),
    "keys": ("ftsweep.cli.keys", "keys"),
    "bench": ("ftsweep.cli.tools", "bench"),
}
# the order `ftsweep --help` lists them: a run's (sweep → status → select → export → verify),
# then one case and the cube's other tools, the kinds' own commands, and the house-keeping ones
WORKFLOW = (
    "sweep",
    "status",
    "select",
    "export",
    "verify",
    "predict",
    "report",
    "compare",
    "estimate",
    "optimize",
    "measure",
    "correct",
)


def kind_commands() -> dict[str, click.Command]:
    """The commands the kinds add (``dpath``, ``fresnel``, a plug-in's), by name: each kind's
    :meth:`~ftsweep.engine.contract.ProgramKind.commands`, which loads no kernel; a name of
    :data:`COMMANDS` is never taken."""
    from ftsweep import registry

    found: dict[str, click.Command] = {}
    for kind in registry.kinds().values():
        for command in kind.commands():
            if command.name and command.name not in COMMANDS:
                found.setdefault(command.name, command)
    return found


def commands() -> list[str]:
    """The name of every command but ``catalogs``: :data:`COMMANDS`, then the kinds' own."""
    return [*COMMANDS, *kind_commands()]


def short_help(name: str, limit: int = 45) -> str:
    """The one-line summary of command ``name`` as click makes it from the command's docstring;
    for one of :data:`COMMANDS`, read from its module's source without importing the module."""
    if name not in COMMANDS:
        return kind_commands()[name].get_short_help_str(limit)
    module, function = COMMANDS[name]
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None
    with open(spec.origin, encoding="utf-8") as f:
        tree = ast.parse(f.read())
    doc = next(
        ast.get_docstring(node, clean=False) or ""
        for node in tree.body
        if isinstance(node, ast.FunctionDef) and node.name == function
    )
    # a bare command with the same help text makes the summary exactly as click does
    return click.Command(name, help=doc).get_short_help_str(limit)


class _Group(click.Group):
    """Turns every error into a one-line message and a non-zero exit (no traceback); set
    FTSWEEP_DEBUG=1 to see the traceback of an unexpected one. Its commands are loaded when
    first asked for (:func:`commands`)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        known = [*self.commands, *commands()]
        last = ("catalogs", "keys", "bench")
        rest = sorted({n for n in known if n not in WORKFLOW and n not in last})
        return [*(n for n in WORKFLOW if n in known), *rest, *(n for n in last if n in known)]

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        """click's, with a "did you mean" for a misspelt command."""
        try:
            return super().resolve_command(ctx, args)
        except click.UsageError:
            name = args[0] if args else ""
            known = self.list_commands(ctx)
            if name and not name.startswith("-") and name not in known:
                from ftsweep.inputs.strict import did_you_mean

                raise click.UsageError(f"No such command {name!r}{did_you_mean(name, known)}.", ctx) from None
            raise

    def get_command(self, ctx: click.Context, cmd_name: str) -> Optional[click.Command]:
        if cmd_name not in self.commands:
            if cmd_name in COMMANDS:
                module, function = COMMANDS[cmd_name]
                self.add_command(getattr(importlib.import_module(module), function), cmd_name)
            elif cmd_name in (added := kind_commands()):
                self.add_command(added[cmd_name], cmd_name)
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = [
            (n, self.commands[n].get_short_help_str(limit) if n in self.commands else short_help(n, limit))
            for n in names
        ]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

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
            cause = user_cause(exc)
            known = isinstance(exc, USER_ERRORS) or cause is not None
            hint = "" if known else " (an unexpected error: set FTSWEEP_DEBUG=1 for the traceback)"
            text = cause or (str(exc) if known and str(exc) else f"{type(exc).__name__}: {exc}")
            raise click.ClickException(one_line(text, MESSAGE_LIMIT - len(hint)) + hint) from None


# object storage's refusals that a user's set-up causes (botocore's, by name: not imported here)
CREDENTIAL_ERRORS = frozenset({"NoCredentialsError", "PartialCredentialsError", "NoRegionError"})


def user_cause(exc: BaseException) -> Optional[str]:
    """The one-line cause of an error a user's input or set-up made that is not one of
    :data:`USER_ERRORS`: missing object-storage credentials, a number out of range."""
    name = type(exc).__name__
    if name in CREDENTIAL_ERRORS:
        return (
            f"object storage refused to start: {name}: {exc}. Give credentials (AWS_ACCESS_KEY_ID and "
            "AWS_SECRET_ACCESS_KEY, a profile, or --storage-option key=... --storage-option secret=...), "
            "or --storage-option anon=true for a public bucket"
        )
    if isinstance(exc, OverflowError):
        return f"a number is out of range ({exc}): check the magnitudes of the options and entries given"
    return None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="ftsweep")
def main() -> None:
    """Control-point layouts for fast-tool-servo (FTS) diamond turning.

    An FTS controller moves the tool by bilinear interpolation in a table of control
    points (in polar coordinates or on a Cartesian grid). ftsweep predicts the form
    error a layout leaves on the machined part, including tool-nose compensation and the
    tool-arc envelope (the model is in the README, section "The model").

    \b
    Units: lengths µm, errors nm, angles degrees, feed µm/rev.
    Catalogs (surfaces, machines, cutting conditions, sweeps) are YAML files in the folder
    named by $FTSWEEP_CATALOGS, else a checkout's catalogs/ (an editable install), else the
    copy the installed package ships; surface families of your own come from plug-ins
    (entry points 'ftsweep.surfaces', or $FTSWEEP_SURFACE_MODULES). `ftsweep catalogs`
    lists them with the folder read and where each family comes from.
    """
    from ftsweep.engine import allocator

    # figures go to files here: pyplot's file backend unless the user chose one; the library
    # itself never switches a caller's backend (a notebook's plots would stop showing)
    os.environ.setdefault("MPLBACKEND", "Agg")
    allocator.tune()  # large batch temporaries reused, not page-faulted afresh (see the module)
    # a library warning (e.g. resuming a cube another code revision started) is one line on
    # stderr, not a file path, a line number and the source line that raised it
    warnings.formatwarning = _one_line_warning


def _one_line_warning(message: Any, category: Any, *_: Any, **__: Any) -> str:
    return f"Warning: {message}\n"


@main.command("catalogs")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def list_catalogs(as_json: bool) -> None:
    """List the surfaces, machines, cutting conditions and sweeps the catalogs define, the
    folder they are read from and why, and the surface families with where each comes from.

    \b
    The folder: $FTSWEEP_CATALOGS where set, else the checkout's catalogs/ (an editable
    install), else the copy a regular install ships (ftsweep/catalogs_data). Surface families:
    ftsweep's own, plus those of plug-ins: modules named by entry points of group
    'ftsweep.surfaces' of installed packages, or by $FTSWEEP_SURFACE_MODULES (comma-separated).

    Descriptions are printed whole, wrapped to the terminal. With --json, one object maps
    each kind to its entries (every field, units in the field names) and the sweep names.
    """
    import shutil
    import textwrap

    from ftsweep.inputs import catalogs, surfaceplugins
    from ftsweep.sweeps.spec import sweep_dir

    kinds = ("surfaces", "machines", "cutting")
    found = {kind: catalogs.entries(kind) for kind in kinds}
    sweeps = sorted(p.stem for p in sweep_dir().glob("*.yaml"))
    families = {
        f: surfaceplugins.source_of(f) for f in [*catalogs.registered_surfaces(), *catalogs.USER_FAMILIES]
    }
    if as_json:
        data: dict[str, Any] = {
            kind: {name: spec.model_dump(mode="json") for name, spec in entries.items()}
            for kind, entries in found.items()
        }
        data["sweeps"] = sweeps
        data["catalog_dir"] = str(catalogs.catalog_dir())
        data["catalog_dir_from"] = catalogs.catalog_dir_reason()
        data["surface_families"] = families
        echo_json(data)
        return
    width = max(40, min(shutil.get_terminal_size((100, 24)).columns, 120))
    click.echo(f"catalogs     {catalogs.catalog_dir()} ({catalogs.catalog_dir_reason()})")
    _echo_families(families, width)
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


def _echo_families(families: dict[str, str], width: int) -> None:
    """The surface families, ftsweep's own first, each plug-in's after them with its origin,
    wrapped to ``width``."""
    import textwrap

    own = [f for f, source in families.items() if source.startswith("ftsweep")]
    lines = [f"ftsweep's own: {', '.join(own)}"]
    for source in sorted({s for s in families.values() if not s.startswith("ftsweep")}):
        lines.append(f"{', '.join(f for f, s in families.items() if s == source)}: from {source}")
    for i, line in enumerate(lines):
        head = "families     " if i == 0 else " " * 13
        click.echo(textwrap.fill(line, width=width, initial_indent=head, subsequent_indent=" " * 15))


if __name__ == "__main__":  # pragma: no cover
    main()
