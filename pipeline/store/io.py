"""Small-file writes that never leave a half-written file looking complete."""

from __future__ import annotations

import json
import math
import os
import stat
import tempfile
from pathlib import Path
from typing import Any

from ftsweep.errors import ExportError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def read_regular(
    path: str | os.PathLike[str], cap: int, what: str = "file", head: int | None = None
) -> bytes:
    """The bytes of ``path``, refused (:class:`ExportError`, naming the path) unless it is a
    regular file of at most ``cap`` bytes: a device (``/dev/zero``), a FIFO, a socket or a
    directory is never read, so a read can neither block nor run without end. The file is
    opened without blocking and judged by ``fstat`` of the open descriptor, so swapping the
    path for a FIFO after a first look changes nothing. ``head``: read only that many
    bytes from the start."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        raise ExportError(f"{path}: cannot open it ({exc.strerror or exc})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_size > cap:
        os.close(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = "a directory" if stat.S_ISDIR(info.st_mode) else "a device, FIFO or socket"
            raise ExportError(f"{path} is {kind}, not a regular {what}; nothing was read")
        raise ExportError(
            f"{path} holds {info.st_size:,} bytes, more than any {what} ftsweep reads ({cap:,}); "
            "nothing was read"
        )
    with os.fdopen(fd, "rb") as fh:
        data = fh.read(cap + 1 if head is None else min(head, cap + 1))
    if len(data) > cap:  # grew while being read
        raise ExportError(f"{path} grew past {cap:,} bytes while it was read; nothing was used")
    return data


# a program holds at most a controller's block count: this bounds what verify and predict read
# (ftsweep's largest, a 1.85M-point four-axis Fresnel program, is ~110 MB)
MAX_PROGRAM_BYTES = 256 * 2**20
# a sidecar holds a case, its catalog entries and at most a controller's layer schedule
MAX_SIDECAR_BYTES = 64 * 2**20


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:40]} does not fit a float")
    return value


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


def read_sidecar(path: Path, raw: bytes | None = None) -> dict[str, Any]:
    """The sidecar of an exported file (``FILE.json`` beside ``path``), read as untrusted
    data: a regular file of at most :data:`MAX_SIDECAR_BYTES`, strict JSON (no NaN, no
    Infinity, no number that overflows a float), an object, and every string that export
    renders held to :func:`ftsweep.freetext.check_text`; :class:`ExportError` naming the
    problem otherwise. ``raw``: the sidecar's bytes, read already."""
    side = sidecar_of(Path(path))
    try:
        raw = read_regular(side, MAX_SIDECAR_BYTES, "sidecar") if raw is None else raw
    except ExportError as exc:
        if not side.exists():
            raise ExportError(f"{side} is missing: verify needs the sidecar written with the file") from None
        raise exc from None
    try:
        meta = json.loads(raw.decode("utf-8"), parse_float=_finite, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise ExportError(
            f"{side} is not an ftsweep sidecar ({type(exc).__name__}: {str(exc)[:100]})"
        ) from None
    if not isinstance(meta, dict):
        raise ExportError(f"{side} is not an ftsweep sidecar (a JSON object is expected)")
    check_sidecar_text(meta, side, "do not load the file")
    return meta


def check_sidecar_text(meta: dict[str, Any], side: Path, then: str) -> None:
    """Every string of a sidecar that export renders held to the strict character set
    (:func:`ftsweep.freetext.check_strings`); :class:`ExportError` naming the field, then
    ``then`` (what follows for the user)."""
    from ftsweep.freetext import TextError, check_strings

    try:
        check_strings(meta, side.name)
    except TextError as exc:
        raise ExportError(f"{side}: {exc}; {then}") from None


def sidecar_path(path: Path) -> Path:
    """``FILE.ext.json`` beside ``FILE.ext``, named from the whole file name (``part.nc`` and
    ``part.pmc`` of one case never share a sidecar), as signatures are (``FILE.ext.sig``)."""
    return path.with_name(path.name + ".json")


def older_sidecar_path(path: Path) -> Path:
    """``FILE.json`` beside ``FILE.ext``: the sidecar's name before it was named from the
    whole file name (still read, :func:`sidecar_of`)."""
    return path.with_suffix(".json")


def sidecar_of(path: Path) -> Path:
    """The sidecar a reader takes for ``path``: ``FILE.ext.json``, or, where only a sidecar of
    the older name exists (``FILE.json``, exports before the whole name was used), that one;
    verify says so in a note."""
    path = Path(path)
    new = sidecar_path(path)
    old = older_sidecar_path(path)
    if not new.exists() and old != path and path.suffix and old.exists():
        return old
    return new


def check_overwrite(paths: tuple[Path, ...], force: bool) -> None:
    """Refuse to replace an existing file unless ``force`` (every exported kind writes a file
    and its sidecar as one unit: neither is replaced without ``--force``)."""
    for path in paths:
        if Path(path).exists() and not force:
            raise ExportError(f"{path} exists; give --force to replace it")


def write_temporary(target: Path, text: str | bytes) -> Path:
    """A complete, synced temporary file beside ``target`` holding ``text`` (a string, written
    as UTF-8, or bytes as they are), with the permissions a plain ``open`` would give
    (mkstemp's own are 0600 whatever the umask)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(text.encode("utf-8") if isinstance(text, str) else text)
            fh.flush()
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
            os.fsync(fh.fileno())
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        # a full disk (ENOSPC) or quota says nothing of the file: name it
        raise OSError(
            exc.errno, f"{target}: cannot write it ({exc.strerror or exc}); nothing was replaced"
        ) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename,
    so readers see either the old file or the complete new one."""
    return write_texts_atomic({Path(path): text})[0]


def write_texts_atomic(files: dict[Path, str | bytes]) -> list[Path]:
    """Write several files as one unit: every temporary is complete before the first rename,
    and if a rename fails the files already renamed are removed again, so a reader never finds
    part of the set new (a kill between two renames can still leave a mixed pair; readers
    that must know check each other's hashes, as ``verify`` does)."""
    temps: dict[Path, Path] = {}
    done: list[Path] = []
    try:
        for target, text in files.items():
            temps[target] = write_temporary(Path(target), text)
        for target, tmp in temps.items():
            os.replace(tmp, target)
            done.append(Path(target))
    except BaseException:
        for tmp in temps.values():
            tmp.unlink(missing_ok=True)
        for target in done:
            Path(target).unlink(missing_ok=True)
        raise
    return [Path(t) for t in files]


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float (a metric not simulated, e.g. ``pv_interp_nm``
    with ``interp_error`` off) replaced by None, so it serialises as strict JSON (null)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def dumps_json(value: Any, **options: Any) -> str:
    """Strict JSON of ``value`` (:func:`json_safe`): the one serialiser of every JSON the
    project prints or writes, so no output carries NaN and none fails on it."""
    return json.dumps(json_safe(value), allow_nan=False, **options)


def write_json_atomic(path: str | os.PathLike[str], data: Any) -> Path:
    """:func:`write_text_atomic` of ``data`` as indented strict JSON (:func:`dumps_json`)."""
    return write_text_atomic(path, dumps_json(data, indent=2) + "\n")


def new_axes(ax: Any = None, size: tuple[float, float] = (7.0, 4.6)) -> Any:
    """``ax``, or the axes of a new figure on pyplot's backend as the caller has it (a
    notebook's inline one stays; the command line sets Agg for itself, ``ftsweep.cli.main``).
    Here, not beside the plots of cubes, so that plotting a study imports no xarray."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=size, layout="constrained")
    return ax


def stacked_axes(rows: int, size: tuple[float, float], sharex: bool = False) -> Any:
    """``rows`` axes stacked in a new figure of ``size`` inches, with margins fixed in inches:
    room for the tick labels and a label at each side and a title on top (constrained layout
    measured every artist twice to find about the same margins: 0.1–0.2 s a figure). The
    figure is matplotlib's own, outside pyplot (it is made to be saved by
    :func:`save_figure`): no backend is chosen or started, so it may be drawn on any thread."""
    from matplotlib.figure import Figure

    width, height = size
    gap = 0.15 if sharex else 0.45  # [in] between axes: inner tick labels shown or not
    left, right, bottom, top = 0.9, 0.15, 0.55, 0.35  # [in]
    each = (height - bottom - top - gap * (rows - 1)) / rows
    fig = Figure(figsize=size)
    fig.subplots_adjust(
        left=left / width,
        right=1.0 - right / width,
        bottom=bottom / height,
        top=1.0 - top / height,
        hspace=gap / each,
    )
    return fig.subplots(rows, 1, sharex=sharex)


def save_figure(fig: Any, path: Path, dpi: int = 110) -> Path:
    """Save a matplotlib figure to ``path`` through a temporary file and a rename (no
    half-written PNG), with the permissions the umask gives a plain ``open``; closes it."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)
        if fig.canvas.manager is not None:  # pyplot's: let it go; a bare Figure is only ours
            import matplotlib.pyplot as plt

            plt.close(fig)
    return path
