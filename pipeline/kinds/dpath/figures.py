"""The D-path study's figures ([5] figs. 3 and 7) drawn from plain arrays, with numpy and
matplotlib alone: what they show is formed by :mod:`ftsweep.kinds.dpath.study`
(:func:`~ftsweep.kinds.dpath.study.x_motion_curves`,
:func:`~ftsweep.kinds.dpath.study.z_motion_curves`), and the
drawing can run in a process of its own while the study's cases run
(:class:`Plots`): importing this module loads no kernel, no catalog."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

from ftsweep.store.io import save_figure, stacked_axes


def ready() -> None:
    """Import what drawing a figure needs, ahead of the first figure (matplotlib's figure
    and its PNG canvas: ~0.3–0.6 s, paid while the study plans its paths)."""
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401


def draw_x_motion(curves: dict[str, dict[str, Any]], title: str, out: Path) -> Path:
    """[5] fig. 3 from :func:`ftsweep.kinds.dpath.study.x_motion_curves`: ρ [mm], X feed [mm/s] and X
    acceleration [m/s²] against the polar angle [deg], one line per transition; saved to
    ``out`` (PNG, :func:`ftsweep.store.io.save_figure`)."""
    axes = stacked_axes(3, (8.0, 7.5), sharex=True)
    for kind, c in curves.items():
        axes[0].plot(c["deg"], c["rho_mm"], label=kind)
        # velocities belong to the steps between samples: drawn at the steps' middles
        axes[1].plot(c["mid_deg"], c["x_feed_mm_s"], label=kind)
        axes[2].plot(c["deg"], c["x_accel_m_s2"], label=kind)
    axes[0].set_ylabel("ρ = X [mm]")
    axes[1].set_ylabel("X feed [mm/s]")
    axes[2].set_ylabel("X acceleration [m/s²]")
    axes[2].set_xlabel("polar angle θ (accumulated C) [deg]")
    axes[0].set_title(title, fontsize=9)
    return _finish(axes, out)


def draw_z_motion(curves: dict[str, dict[str, Any]], out: Path) -> Path:
    """[5] fig. 7 from :func:`ftsweep.kinds.dpath.study.z_motion_curves`: Z [µm] and Z velocity [mm/s]
    against C within one revolution [deg], the spiral's and the D path's; saved to ``out``."""
    axes = stacked_axes(2, (8.0, 6.0))
    for name, c in curves.items():
        axes[0].plot(c["deg"], c["z_um"], label=name)
        # velocities belong to the steps between points (drawn from each step's start)
        axes[1].plot(c["step_deg"], c["z_velocity_mm_s"], label=name)
    axes[0].set_ylabel("Z [µm]")
    axes[1].set_ylabel("Z velocity [mm/s]")
    axes[1].set_xlabel("C within one revolution [deg]")
    axes[0].set_title(
        "Z motion over one revolution: spiral (mid-radius) against D path (mid-zone cut)", fontsize=9
    )
    return _finish(axes, out)


def _finish(axes: Any, out: Path) -> Path:
    for a in axes:
        a.grid(True, alpha=0.3)
        a.legend(fontsize=7)
    return save_figure(axes[0].figure, out)


class Plots:
    """A D-path study's two figures as ``folder``/dpath-<surface>-x.png and -z.png, drawn by a
    process of its own while the study runs: :func:`ftsweep.kinds.dpath.study.study` hands each its
    curves as soon as they are known (fig. 3's once the paths are planned, fig. 7's once the
    spiral's motion is). Drawn after the study they were a third of the seed example's
    command; a thread would not do: importing matplotlib and drawing hold the GIL, which each
    of the cases' kernels waits for between batches. The process imports numpy and matplotlib
    alone (this module), from the start, while the command imports the study's modules.

    Where no process can be started (no POSIX semaphores, a process limit: a warning says
    why), the figures are drawn here when :meth:`paths` is called, after the study.
    :meth:`paths` waits for the figures, raises what drawing raised and ends the process;
    leaving a ``with`` drops what is not started and waits for the rest, or, left by an error
    (bad input found by the study), ends the process at once rather than wait for its imports."""

    def __init__(self, folder: Path, surface: str) -> None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        folder.mkdir(parents=True, exist_ok=True)
        self.x_path = folder / f"dpath-{surface}-x.png"
        self.z_path = folder / f"dpath-{surface}-z.png"
        self._jobs: dict[str, Any] = {}  # by figure: handed in from any of the study's threads
        self._pool: Optional[ProcessPoolExecutor] = None
        self._process: set[Any] = set()
        before = set(multiprocessing.active_children())
        try:
            # spawned, not forked: the study's threads may hold locks a fork would copy held
            self._pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
            self._pool.submit(ready)  # starts the process
        except (OSError, NotImplementedError) as exc:
            import warnings

            self.close()
            self._pool = None
            warnings.warn(
                f"the D-path plots are drawn after the study: no process can be started ({exc})", stacklevel=2
            )
        # the pool's own process (the executor gives no handle on it before Python 3.14; made
        # before the study starts, nothing else starts a process in between)
        self._process = set(multiprocessing.active_children()) - before

    def _submit(self, draw: Callable[..., Path], *args: Any) -> Any:
        return _Later(draw, *args) if self._pool is None else self._pool.submit(draw, *args)

    def x_motion(self, curves: dict[str, dict[str, Any]], title: str) -> None:
        """Fig. 3 (:func:`draw_x_motion`) of ``curves``, queued."""
        self._jobs["x"] = self._submit(draw_x_motion, curves, title, self.x_path)

    def z_motion(self, curves: dict[str, dict[str, Any]]) -> None:
        """Fig. 7 (:func:`draw_z_motion`) of ``curves``, queued."""
        self._jobs["z"] = self._submit(draw_z_motion, curves, self.z_path)

    def paths(self) -> list[Path]:
        """The figures' files (fig. 3's, then fig. 7's, those asked for), once drawn."""
        from concurrent.futures.process import BrokenProcessPool

        try:
            return [self._jobs[k].result() for k in ("x", "z") if k in self._jobs]
        except BrokenProcessPool:
            raise RuntimeError("the process drawing the D-path plots ended before drawing them") from None
        finally:
            # drawn (or failed): nothing is left for the process, whose interpreter's
            # teardown with matplotlib loaded is ~0.1 s nobody need wait for
            self.close(abandon=True)

    def close(self, abandon: bool = False) -> None:
        """Shut the process down once its figures are drawn; with ``abandon``, end it now."""
        if self._pool is None:
            return
        if abandon:
            for process in self._process:
                process.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> Plots:
        return self

    def __exit__(self, kind: Any, *exc: Any) -> None:
        self.close(abandon=kind is not None)


class _Later:
    """A figure :class:`Plots` draws here, when its file is asked for (where no process can
    be started)."""

    def __init__(self, draw: Callable[..., Path], *args: Any) -> None:
        self.draw, self.args = draw, args

    def result(self) -> Path:
        return self.draw(*self.args)
