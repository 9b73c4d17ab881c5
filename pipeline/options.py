"""The command line's building blocks that the kinds' options and commands share with
:mod:`ftsweep.cli`: option types that refuse NaN and infinities at parse time (units in the
option's name), ``--threads``, ``--sign-key`` and ``--expires``, strict JSON on stdout, progress
on stderr and one-line messages. A kind declares its ``predict`` options and its commands
with these (docs/architecture.md, "The program-kind contract"), so it leans on nothing above it.
"""

from __future__ import annotations

import functools
import math
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.inputs.strict import check_physical, unit_of
from ftsweep.store.io import dumps_json

__all__ = [
    "COUNT",
    "FINITE",
    "MESSAGE_LIMIT",
    "NON_NEGATIVE",
    "POSITIVE",
    "Expiry",
    "FiniteRange",
    "echo_json",
    "flag",
    "one_line",
    "refuse_overwrite",
    "progress_done",
    "sign_options",
    "stack",
    "stderr_progress",
    "threads_option",
    "unit_words",
]


def flag(name: str) -> str:
    """The command-line option of a field: ``drho_um`` → ``--drho-um``."""
    return "--" + name.replace("_", "-")


def unit_words(name: str) -> str:
    """`` of µm`` for an option named ``..._um`` (its units, from its name), else ``""``."""
    unit = unit_of(name)
    return "" if unit is None else f" of {unit[2]}"


def stack(options: list[Any]) -> Any:
    """One decorator applying ``options`` (click decorators) in the order listed, so that
    ``--help`` shows them in that order."""

    def apply(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return apply


class FiniteRange(click.FloatRange):
    """A finite float within a range; click refuses anything else naming the option."""

    def convert(self, value: Any, param: Optional[click.Parameter], ctx: Optional[click.Context]) -> Any:
        if not isinstance(value, (int, float)):
            try:
                float(value)
            except (TypeError, ValueError):
                name = param.name if param is not None and param.name else ""
                self.fail(f"takes a number{unit_words(name)}, e.g. 2 (got {str(value)[:40]!r})", param, ctx)
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{number} is not a finite number", param, ctx)
        if param is not None and param.name:
            problem = check_physical(param.name, number)  # 1e308 µm, points, a 1e-300 µm radius
            if problem:
                self.fail(problem.replace(param.name, flag(param.name), 1), param, ctx)
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


MESSAGE_LIMIT = 1500


def one_line(text: str, limit: int = MESSAGE_LIMIT) -> str:
    """A message on one line: its lines joined with "; ", whitespace collapsed and the whole
    cut at ``limit`` characters, so no input, however large, is echoed in full."""
    parts = [" ".join(line.split()) for line in str(text).splitlines()]
    joined = "; ".join(p for p in parts if p).replace(":; ", ": ")
    return joined if len(joined) <= limit else joined[: limit - 1] + "…"


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


def refuse_overwrite(out: Optional[Path], force: bool) -> None:
    """Refuse, before any work, to replace an existing program or its sidecar without --force."""
    from ftsweep.errors import ExportError
    from ftsweep.store.io import check_overwrite, sidecar_path

    if out is not None:
        try:
            check_overwrite((out, sidecar_path(out)), force)
        except ExportError as exc:
            raise click.ClickException(str(exc)) from None
