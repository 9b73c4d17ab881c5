"""What every ``ftsweep`` command shares: option types that refuse NaN and infinities at
parse time, the one-line error format, strict JSON on stdout, progress on stderr and the
``--trust-plugins`` option."""

from __future__ import annotations

import functools
import math
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.inputs.strict import check_physical
from ftsweep.store.io import dumps_json


class FiniteRange(click.FloatRange):
    """A finite float within a range; click refuses anything else naming the option."""

    def convert(self, value: Any, param: Optional[click.Parameter], ctx: Optional[click.Context]) -> Any:
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{number} is not a finite number", param, ctx)
        if param is not None and param.name:
            problem = check_physical(param.name, number)  # 1e308 µm, points, a 1e-300 µm radius
            if problem:
                self.fail(problem.replace(param.name, f"--{param.name.replace('_', '-')}", 1), param, ctx)
        return number

    def _describe_range(self) -> str:
        # click prints "x<=None" for a range without bounds
        if self.min is None and self.max is None:
            return "finite"
        return str(super()._describe_range())


FINITE = FiniteRange()
POSITIVE = FiniteRange(min=0.0, min_open=True)
NON_NEGATIVE = FiniteRange(min=0.0)
COUNT = click.IntRange(min=1)

# exported files and cubes are data: the plug-ins they name run only from the local catalog
TRUST_PLUGINS = click.option(
    "--trust-plugins",
    is_flag=True,
    help="Run a plug-in surface the file names even if the local catalog does not declare it "
    "(plug-ins are code: only for files you trust; README 'Trust').",
)


class Expiry(click.ParamType):
    """When a signature stops being valid: a duration from now (``30d``, ``12h``) or a UTC
    date or time (``2027-01-31``, ``2027-01-31T18:00``); later than now."""

    name = "when"

    def convert(self, value: Any, param: Optional[click.Parameter], ctx: Optional[click.Context]) -> Any:
        if isinstance(value, datetime):
            return value
        text, now = str(value).strip(), datetime.now(UTC)
        try:
            if text[-1:] in ("d", "h") and text[:-1].isdigit():
                hours = int(text[:-1]) * (24 if text[-1] == "d" else 1)
                if not 0 < hours <= 24 * 3660:
                    raise ValueError
                return now + timedelta(hours=hours)
            when = datetime.fromisoformat(text)
        except (ValueError, IndexError, OverflowError):
            self.fail(
                f"{text[:40]!r} is neither a duration (30d, 12h) nor a date (2027-01-31[T18:00])", param, ctx
            )
        when = when if when.tzinfo else when.replace(tzinfo=UTC)
        if when <= now:
            self.fail(f"{text} has passed (now {now:%Y-%m-%dT%H:%M}Z)", param, ctx)
        return when


# ftsweep.exports.origin: who made an exported file, and until when its statement holds
def sign_options(command: Any) -> Any:
    """``--sign-key`` and ``--expires`` of every command that writes an exported file."""
    command = click.option(
        "--expires",
        type=Expiry(),
        help="The signed statement expires then: a duration (30d, 12h) or a UTC date or time "
        "(2027-01-31, 2027-01-31T18:00); verify with a trusted key refuses the file after it. "
        "Default: no expiry.",
    )(command)
    return click.option(
        "--sign-key",
        type=click.Path(dir_okay=False),
        help="Sign a statement of what is written (file name, length, digests, case, surface, machine, "
        "cutting, compensation, dialect, time) with this ed25519 private key (FILE.sig beside it; "
        "`ftsweep keys new` makes one). Default: FTSWEEP_SIGNING_KEY, else signing_key of the config "
        "file; none: not signed.",
    )(command)


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
            self.fail(f"{text!r} does not exist", param, ctx)
        if not path.is_dir():
            self.fail(f"{text!r} is a file, not a cube (a Zarr folder)", param, ctx)
        return text


CUBE = CubeLocation()

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


def threads_option(command: Any) -> Any:
    """Add ``--threads N`` to a command that simulates one case at a time: its cases run on N
    threads each (:func:`ftsweep.engine.threads.using_threads`), by default on every usable core."""

    @functools.wraps(command)
    def run(*args: Any, threads: Optional[int] = None, **kwargs: Any) -> Any:
        from ftsweep.defaults import usable_cores
        from ftsweep.engine.threads import using_threads

        with using_threads(threads or usable_cores()):
            return command(*args, **kwargs)

    return click.option(
        "--threads",
        type=COUNT,
        help="Threads per simulated case: its batches of lines and its table's compensation run "
        "in parallel (the kernels release the GIL); results are the same for any number. "
        "Default: every core this process may use.",
    )(run)


def fail(message: str) -> None:
    raise click.UsageError(message)


MESSAGE_LIMIT = 1500


def one_line(text: str, limit: int = MESSAGE_LIMIT) -> str:
    """A message on one line: its lines joined with "; ", whitespace collapsed and the whole
    cut at ``limit`` characters, so no input, however large, is echoed in full."""
    parts = [" ".join(line.split()) for line in str(text).splitlines()]
    joined = "; ".join(p for p in parts if p).replace(":; ", ": ")
    return joined if len(joined) <= limit else joined[: limit - 1] + "…"


# errors a user can cause: shown as one line, exit 1, no traceback
USER_ERRORS: tuple[type[BaseException], ...] = (
    ValueError,
    OSError,
    RuntimeError,
    MemoryError,
    RecursionError,
)


def _nan_safe(value: Any) -> Any:  # pragma: no cover - only non-JSON types reach here
    return str(value)


def echo_json(value: Any) -> None:
    """Exactly one strict JSON document on stdout."""
    click.echo(dumps_json(value, default=_nan_safe))


def stderr_progress(label: str, quiet: bool = False) -> Any:
    """Progress on stderr (:mod:`ftsweep.progress`): a bar on a terminal, plain lines in a log."""
    from ftsweep import progress

    return progress.progress(label, quiet)


def progress_done(bar: Any) -> None:
    from ftsweep import progress

    progress.done(bar)


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
