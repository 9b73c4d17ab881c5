"""What the cube and export commands share: cube locations and their storage options,
``--allow-incomplete``, ``--trust-plugins``, local outputs, the kinds as a choice and the
errors shown in one line. The blocks every command uses, the kinds' included (option types,
JSON, progress, ``--threads``, signing), are :mod:`ftsweep.options`, re-exported here."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.options import (  # noqa: F401  (the commands' shared blocks, re-exported for cli/)
    COUNT,
    FINITE,
    MESSAGE_LIMIT,
    NON_NEGATIVE,
    POSITIVE,
    Expiry,
    FiniteRange,
    echo_json,
    one_line,
    progress_done,
    sign_options,
    stderr_progress,
    threads_option,
)

# exported files and cubes are data: the plug-ins they name run only from the local catalog
TRUST_PLUGINS = click.option(
    "--trust-plugins",
    is_flag=True,
    help="Run a plug-in surface the file names even if the local catalog does not declare it "
    "(plug-ins are code: only for files you trust; docs/guide.md 'Trust').",
)


class CubeLocation(click.ParamType):
    """A cube: a local folder (which must exist) or an fsspec URL (``s3://bucket/c.zarr``, checked
    when opened); the value stays text so a URL is not mangled into a path."""

    name = "cube"

    def convert(self, value: Any, param: Optional[click.Parameter], ctx: Optional[click.Context]) -> str:
        text = str(value)
        if "://" in text and not text.startswith("file://"):
            return text
        path = Path(text.removeprefix("file://"))
        if not path.exists():
            self.fail(f"{text!r} does not exist: {_maker_of(path)}", param, ctx)
        if not path.is_dir():
            self.fail(f"{text!r} is a file, not a cube (a Zarr folder)", param, ctx)
        return text


CUBE = CubeLocation()


def _maker_of(path: Path) -> str:
    """The cubes beside a missing ``path`` (the closest names first: a mistyped name), or which
    command makes the cube there: the catalog sweep of its name, else any sweep."""
    from ftsweep.inputs.strict import did_you_mean
    from ftsweep.sweeps.spec import sweep_dir

    folder = path.parent if str(path.parent) else Path(".")
    try:
        near = sorted(p.name for p in folder.iterdir() if p.suffix == ".zarr" and p.is_dir())[:200]
    except OSError:  # no such folder, or not readable: nothing beside it to name
        near = []
    stem = path.name.removesuffix(".zarr")
    if stem and (sweep_dir() / f"{stem}.yaml").is_file():
        default = Path("outputs") / f"{stem}.zarr"
        out = "" if path == default else f" --out {path}"
        maker = f"run `ftsweep sweep {stem}{out}` first"
    else:
        maker = f"run `ftsweep sweep SWEEP --out {path}` first (`ftsweep catalogs` lists the sweeps)"
    if not near:
        return maker
    guess = did_you_mean(path.name, near)
    shown = ", ".join(str(folder / n) for n in near[:6]) + (" ..." if len(near) > 6 else "")
    return f"no cube of that name{guess}; cubes in {folder}: {shown}; or {maker}"


# storage options of a cube given as a URL; the usual places come first (fsspec's configuration)
ALLOW_INCOMPLETE = click.option(
    "--allow-incomplete",
    is_flag=True,
    help="Choose from a cube whose cases are not all computed (pending, failed or pruned ones "
    "could change the choice); it is said on stderr.",
)


def guard_complete(status: Any, allow: bool) -> None:
    """Refuse a choice from a cube whose case ``status`` is incomplete unless ``allow`` (then
    say how incomplete, on stderr, in one line)."""
    from ftsweep.tools.select import SelectError, check_complete

    try:
        note = check_complete(status, allow)
    except SelectError as exc:
        raise click.ClickException(str(exc)) from None
    if note is not None:
        click.echo(f"note: {note}", err=True)


STORAGE_OPTIONS = click.option(
    "--storage-option",
    "storage_options",
    multiple=True,
    metavar="KEY=VALUE",
    help="An fsspec storage option for a cube given as a URL (repeat for more; VALUE is JSON when it "
    "parses), e.g. --storage-option endpoint_url=http://127.0.0.1:9000. Options also come from "
    "fsspec's configuration (FSSPEC_S3_ENDPOINT_URL=..., ~/.config/fsspec) and the store's own "
    "(AWS_* variables, ~/.aws).",
)


def cube_place(text: str, storage_options: tuple[str, ...]) -> Any:
    """The :class:`~ftsweep.store.storage.Place` of a CUBE argument or ``--out`` with its options;
    a malformed option is a usage error."""
    from ftsweep.store.storage import StorageError, parse_options, place

    try:
        return place(text, parse_options(storage_options))
    except StorageError as exc:
        raise click.BadParameter(str(exc), param_hint="--storage-option") from None


def local_output(text: Optional[str], what: str) -> Optional[Path]:
    """A local path for a file or folder ftsweep writes; a URL is refused (a header goes to the
    controller from a disk, a report is opened in a browser), saying how to get it there."""
    if text is None:
        return None
    if "://" in text and not text.startswith("file://"):
        raise click.BadParameter(
            f"{what} is written to a local path, not {text}; write it here and copy it with your "
            "storage's tools (aws s3 cp, gsutil cp, ...)",
            param_hint="-o/--out",
        )
    return Path(text.removeprefix("file://"))


def fail(message: str) -> None:
    raise click.UsageError(message)


# errors a user can cause: shown as one line, exit 1, no traceback
USER_ERRORS: tuple[type[BaseException], ...] = (
    ValueError,
    OSError,
    RuntimeError,
    MemoryError,
    RecursionError,
)


class KindChoice(click.Choice):
    """The registered program kinds as a choice (:func:`ftsweep.registry.names`), read when
    the command runs or shows its help, so a kind registered later is offered too."""

    def __init__(self) -> None:
        super().__init__(())

    @property  # type: ignore[override]
    def choices(self) -> tuple[str, ...]:
        from ftsweep import registry

        return registry.names()

    @choices.setter
    def choices(self, value: Any) -> None:
        pass  # click sets its choices once; these are the registry's


class DialectChoice(click.Choice):
    """The program dialects controllers read (:data:`ftsweep.inputs.controllers.DIALECT_INTERPOLATION`),
    read when the command runs or shows its help, so that importing the command loads no
    catalog model."""

    def __init__(self) -> None:
        super().__init__(())

    @property  # type: ignore[override]
    def choices(self) -> tuple[str, ...]:
        from ftsweep.inputs.controllers import DIALECT_INTERPOLATION

        return tuple(DIALECT_INTERPOLATION)

    @choices.setter
    def choices(self, value: Any) -> None:
        pass  # click sets its choices once; these are the controllers'


class KindsHelp(click.Command):
    """A command whose ``--help`` ends with what every registered kind says of itself
    (:class:`ftsweep.engine.contract.ProgramKind`'s ``description`` and ``exports_as``, or for
    ``predict`` its defaults, ``predict_help`` and ``examples``), read from the registry when
    the help is shown: the command's own text names no kind, and a kind added later is
    described too."""

    def __init__(self, *args: Any, kinds_say: str = "exports_as", **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.kinds_say = kinds_say

    def format_help_text(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        super().format_help_text(ctx, formatter)
        from ftsweep import registry

        kinds = registry.kinds().values()
        with formatter.section("Program kinds"):
            if self.kinds_say == "predict":
                rows = [
                    (k.name, f"{k.description}; default --machine {k.machine}, --cutting {k.cutting}")
                    for k in kinds
                ]
            else:
                rows = [(k.name, f"{k.description}; export writes {k.exports_as}") for k in kinds]
            formatter.write_dl(rows)
            if self.kinds_say == "predict":
                for k in kinds:
                    if k.predict_help:
                        formatter.write_paragraph()
                        formatter.write_text(k.predict_help)
        examples = [line for k in kinds for line in k.examples] if self.kinds_say == "predict" else []
        if examples:
            with formatter.section("Examples of the kinds"):
                for line in examples:
                    formatter.write(f"{'':{formatter.current_indent}}{line}\n")


def first_compile_notice() -> None:
    """On a first run (numba's cache without this install's kernels), say on stderr that they
    compile now, with how long that took when last measured on this machine
    (:func:`ftsweep.caches.recorded_compile_s`), or no figure where none was measured."""
    from ftsweep.caches import recorded_compile_s
    from ftsweep.engine.compiling import kernels_cached

    if not kernels_cached():
        seconds = recorded_compile_s()
        took = f"{seconds:.0f} s when last measured on this machine" if seconds else "not yet measured here"
        click.echo(f"compiling    numba's kernels: a first run of this install ({took}) ...", err=True)


@contextmanager
def reported_errors(progress: Any, *errors: type[Exception]) -> Iterator[Any]:
    """The block's ``progress`` on stderr, ended whatever happens; the ``errors`` a command
    expects are one ``Error:`` line each."""
    try:
        yield progress
    except errors as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        progress_done(progress)
