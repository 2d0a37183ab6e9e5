"""Figures and videos of an evaluation; matplotlib (Agg backend), Pillow and imageio are
imported only when drawing or writing.

* :func:`trajectory_plot`: in the style of the SRPB paper's Fig. 8, the robot paths of every
  episode of one planner in one scenario, coloured by time (colour bar), over the walls,
  with the people's tracked positions faint and the F-formations' O-spaces outlined.
* :func:`bar_chart`: one panel per metric, a bar per planner (median, its 95 % interval as
  the error bar; rates with their Wilson interval), for one scenario; the metrics computed
  from the people get a second, hatched bar per planner: from ground truth.
* :class:`VideoWriter`: ``env.render()`` frames as MP4 through imageio's ffmpeg plugin when
  it is installed (``imageio`` and ``imageio-ffmpeg``), else as an animated GIF (Pillow,
  one palette shared by every frame: the renderer draws few colours).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from importlib.util import find_spec
from typing import Any

import numpy as np

from srpb_gym.metrics import METRIC_NAMES, METRIC_UNITS, MetricParams
from srpb_gym.metrics.episode import evaluate_detailed
from srpb_gym.metrics.record import EpisodeRecord
from srpb_gym.render import ellipse_points

PLOT_HINT = 'pip install "srpb-gym[plot]"'
VIDEO_HINT = "pip install pillow (GIF), or pip install imageio imageio-ffmpeg (MP4)"
MAX_OSPACES = 24  # O-space outlines drawn per episode (evenly spread over its samples)


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend; ``ImportError`` naming the ``plot`` extra."""
    try:
        import matplotlib
    except ImportError as err:
        raise ImportError(f"figures need matplotlib: {PLOT_HINT}") from err
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def trajectory_plot(
    records: Sequence[EpisodeRecord],
    walls: np.ndarray,
    title: str,
    path: str,
    params: MetricParams | None = None,
    semantics: str = "paper",
    people: Sequence[bool] | None = None,
) -> None:
    """Draw the episodes ``records`` of one planner over the ``walls`` (S, 4) into ``path``
    (the people and O-spaces of the records whose ``people`` flag is set; default: all;
    several robots of one episode: the paths of all, the people once)."""
    plt = pyplot()
    from matplotlib.collections import LineCollection

    (x0, y0), (x1, y1) = _extent(walls, records)
    wide = (x1 - x0) > 2.0 * (y1 - y0)
    height = 10.0 * (y1 - y0) / (x1 - x0) * (0.8 if wide else 1.0) + (2.0 if wide else 1.0)
    fig, ax = plt.subplots(figsize=(10.0, min(max(height, 2.5), 8.0)), layout="constrained")
    _draw_walls(ax, walls, LineCollection)
    t_max = max((float(r.robot_col("t")[-1]) for r in records if r.n_samples), default=1.0)
    norm = plt.Normalize(0.0, max(t_max, 1e-9))
    lines = None
    for i, record in enumerate(records):
        if people is None or people[i]:
            _draw_people(ax, record, params or MetricParams(), semantics)
        lines = _draw_path(ax, record, norm, LineCollection) or lines
    if lines is not None:
        fig.colorbar(lines, ax=ax, label="time [s]", location="bottom" if wide else "right",
                     shrink=0.6 if wide else 0.8, aspect=40 if wide else 20)  # fmt: skip
    ax.set(title=title, xlabel="x [m]", ylabel="y [m]", xlim=(x0, x1), ylim=(y0, y1))
    ax.set_aspect("equal")
    ax.legend(handles=_legend_handles(), loc="upper left", bbox_to_anchor=(1.0, 1.0) if wide
              else (0.0, 1.0), fontsize=7, frameon=False)  # fmt: skip
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _extent(walls: np.ndarray, records: Sequence[EpisodeRecord]) -> np.ndarray:
    """(2, 2) lower-left and upper-right corners of everything drawn, with a margin."""
    xy = [np.asarray(walls, dtype=np.float64).reshape(-1, 2)]
    xy += [r.robot[:, 1:3] for r in records if r.n_samples]
    xy += [r.robot[:, 7:9] for r in records if r.n_samples]
    pts = np.concatenate(xy)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.size == 0:
        return np.array([[0.0, 0.0], [1.0, 1.0]])
    return np.array([pts.min(axis=0) - 0.3, pts.max(axis=0) + 0.3])


def _legend_handles() -> list[Any]:
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], color="tab:green", lw=1.6, label="robot path"),
        Line2D([], [], marker="o", ls="", color="0.3", ms=4, label="start"),
        Line2D([], [], marker="*", ls="", color="tab:red", ms=8, label="goal"),
        Line2D([], [], marker="o", ls="", color="tab:blue", alpha=0.5, ms=3,
               label="people (tracked)"),
        Line2D([], [], color="tab:purple", alpha=0.6, lw=0.8, label="O-space"),
        Line2D([], [], color="0.15", lw=2.0, label="walls"),
    ]  # fmt: skip


def _draw_walls(ax: Any, walls: np.ndarray, line_collection: Any) -> None:
    segments = np.asarray(walls, dtype=np.float64).reshape(-1, 2, 2)
    ax.add_collection(line_collection(segments, colors="0.15", linewidths=2.0, zorder=3))


def _draw_people(ax: Any, record: EpisodeRecord, params: MetricParams, semantics: str) -> None:
    """Tracked people as faint dots; O-space outlines of the groups."""
    if record.people.shape[0]:
        ax.scatter(record.people[:, 0], record.people[:, 1], s=3, color="tab:blue",
                   alpha=0.12, linewidths=0, zorder=1)  # fmt: skip
    if record.group_sample.shape[0] == 0 or record.n_samples == 0:
        return
    ellipses = evaluate_detailed(record, semantics, params).ellipses
    rows = np.flatnonzero(np.isfinite(ellipses).all(axis=1))
    rows = rows[np.linspace(0, rows.size - 1, min(rows.size, MAX_OSPACES)).astype(int)]
    for outline in ellipse_points(ellipses[rows]):
        closed = np.vstack([outline, outline[:1]])
        ax.plot(closed[:, 0], closed[:, 1], color="tab:purple", alpha=0.25, lw=0.8, zorder=2)


def _draw_path(ax: Any, record: EpisodeRecord, norm: Any, line_collection: Any) -> Any:
    """The robot's path coloured by time, its start (circle) and goal (star)."""
    if record.n_samples < 2:
        return None
    xy, t = record.robot[:, 1:3], record.robot_col("t")
    segments = np.stack([xy[:-1], xy[1:]], axis=1)
    lines = line_collection(segments, cmap="viridis", norm=norm, linewidths=1.6, zorder=4)
    lines.set_array(0.5 * (t[:-1] + t[1:]))
    ax.add_collection(lines)
    ax.plot(*xy[0], "o", ms=4, color="0.3", zorder=5)
    goal = record.robot[-1, 7:9]
    ax.plot(*goal, "*", ms=10, color="tab:red", zorder=5)
    return lines


def bar_chart(
    planners: dict[str, dict[str, Any]], title: str, path: str, truth: Sequence[str] = ()
) -> None:
    """One panel per metric (and the outcome rates), a bar per planner: the median with its
    95 % interval (``ci_low``, ``ci_high``) as the error bar, a rate with its Wilson
    interval; ``planners`` is one env's summary. The metrics of ``truth`` get two bars per
    planner: from the tracked people (plain) and from ground truth (hatched,
    ``metrics_gt``)."""
    plt = pyplot()
    from matplotlib.patches import Patch

    names = list(planners)
    panels = [f"{o}_rate" for o in ("success", "collision", "timeout")] + list(METRIC_NAMES)
    cols = 6
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.6 * cols, 2.2 * rows + 0.8),
                             layout="constrained", squeeze=False)  # fmt: skip
    colors = plt.get_cmap("tab10")(np.arange(len(names)) % 10)
    x = np.arange(len(names))
    for ax, key in zip(axes.flat, panels):
        median, low, high = _bars(planners, names, key)
        if key in truth:
            gt = _bars(planners, names, key, "metrics_gt")
            ax.bar(x - 0.2, median, 0.4, color=colors, yerr=[low, high], capsize=2,
                   error_kw={"lw": 0.8})  # fmt: skip
            ax.bar(x + 0.2, gt[0], 0.4, color=colors, yerr=[gt[1], gt[2]], capsize=2,
                   error_kw={"lw": 0.8}, hatch="///", alpha=0.55, edgecolor="0.2")  # fmt: skip
            median, high = np.concatenate([median, gt[0]]), np.concatenate([high, gt[2]])
        else:
            ax.bar(x, median, color=colors, yerr=[low, high], capsize=3, error_kw={"lw": 0.8})
        unit = "%" if key.endswith("_rate") else METRIC_UNITS[key]
        ax.set_title(f"{key} [{unit}]", fontsize=9)
        ax.set_xticks(x, names, rotation=30, ha="right", fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        _y_range(ax, median, high)
    for ax in axes.flat[len(panels) :]:
        ax.axis("off")
    if truth:
        fig.legend(handles=[Patch(facecolor="0.6", label="tracked people"),
                            Patch(facecolor="0.6", alpha=0.55, hatch="///", edgecolor="0.2",
                                  label="ground truth")], loc="lower right", fontsize=8,
                   frameon=False)  # fmt: skip
    fig.suptitle(title)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _y_range(ax: Any, median: np.ndarray, high: np.ndarray) -> None:
    """Bars from 0; an all-zero (or undefined) panel gets the range [0, 1]."""
    finite = np.isfinite(median)
    if not finite.any() or np.max(np.abs(median[finite]) + high[finite]) <= 1e-12:
        ax.set_ylim(0.0, 1.0)
    else:
        ax.set_ylim(bottom=min(0.0, float(np.min(median[finite]))))


def _bars(
    planners: dict[str, dict[str, Any]], names: list[str], key: str, group: str = "metrics"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heights and lower/upper error lengths (to the 95 % interval's bounds; 0 where it is
    not computed) of one panel (NaN where undefined); ``group``: ``metrics`` (tracked) or
    ``metrics_gt`` (ground truth)."""
    median, low, high = [], [], []
    for name in names:
        if key.endswith("_rate"):
            value, (lo, hi) = planners[name][key], planners[name].get(f"{key}_ci") or (None, None)
        else:
            s = planners[name].get(group, {}).get(key) or {"median": None}
            value, lo, hi = s["median"], s.get("ci_low"), s.get("ci_high")
        median.append(np.nan if value is None else value)
        low.append(0.0 if value is None or lo is None else value - lo)
        high.append(0.0 if value is None or hi is None else hi - value)
    return np.array(median), np.array(low), np.array(high)


# ---------------------------------------------------------------------------- videos
def video_support() -> str | None:
    """``None`` if videos can be written, else what is missing (one line). The frames come
    from the renderer (pygame-ce, a dependency of srpb-gym); writing them needs Pillow
    (GIF) or imageio with imageio-ffmpeg (MP4)."""
    if find_spec("pygame") is None:
        return "videos need pygame-ce, a dependency of srpb-gym: pip install pygame-ce"
    if video_format() is None:
        return f"videos need Pillow (GIF) or imageio and imageio-ffmpeg (MP4): {VIDEO_HINT}"
    return None


def video_format() -> str | None:
    """``"mp4"`` with imageio's ffmpeg plugin, else ``"gif"`` with Pillow, else ``None``."""
    if find_spec("imageio") is not None and find_spec("imageio_ffmpeg") is not None:
        return "mp4"
    return "gif" if find_spec("PIL") is not None else None


MAX_FRAME_SECONDS = 100.0
"""The longest a video frame is shown: ffmpeg is given the frame rate to two decimals
(0.01 fps at least) and a GIF frame's duration is 16 bits of hundredths of a second
(:class:`VideoWriter` plays a longer stride faster than real time)."""


class VideoWriter:
    """Frames (H, W, 3 uint8) added one at a time, written to ``stem`` + ``.mp4`` (streamed
    through imageio's ffmpeg plugin) or ``.gif`` (each frame kept as 8-bit palette indices,
    the palette fitted to the first frame, which shows every colour in its legend).

    ``fps``: the rate the frames are added at (the environment's ``render_fps``).
    ``stride``: keep the first frame and every ``stride``-th after it, and always the last
    one added (so the video ends where the episode ends), played at ``fps / stride``: the
    same real time in ``1 / stride`` of the frames; but a frame is shown for at most
    :data:`MAX_FRAME_SECONDS` (what both video formats can say), so a stride longer than
    that plays faster than real time."""

    def __init__(self, stem: str, fps: float = 10, stride: int = 1) -> None:
        if stride < 1:
            raise ValueError(f"stride must be at least 1, got {stride}")
        self.format = video_format() or "gif"
        self.path = f"{stem}.{self.format}"
        self.stride = stride
        self.fps = max(fps / stride, 1.0 / MAX_FRAME_SECONDS)
        self._writer: Any = None
        self._palette: Any = None
        self._images: list[Any] = []
        self._added = 0
        self._frames = 0
        self._held: Callable[[], np.ndarray | None] | None = None
        os.makedirs(os.path.dirname(self.path) or ".", exist_ok=True)

    def add(self, frame: np.ndarray | None) -> None:
        """Add one frame (``None`` is skipped); one between strides is held back until the
        next is added, and written by :meth:`close` if it was the last."""
        if frame is not None:
            self.film(lambda: frame)

    def film(self, render: Callable[[], np.ndarray | None]) -> None:
        """Count one frame and call ``render`` (``env.render``) only if it is kept: a frame
        between strides is not drawn, and ``render`` is kept instead, so that :meth:`close`
        draws the last frame if it fell between strides (``close`` then has to come before
        the environment moves on). A ``None`` from ``render`` writes nothing."""
        self._added += 1
        if (self._added - 1) % self.stride:
            self._held = render
            return
        self._held = None
        self._write(render())

    @property
    def frames(self) -> int:
        """Frames written so far (a held-back frame not counted)."""
        return self._frames

    def _write(self, frame: np.ndarray | None) -> None:
        if frame is None:
            return
        frame = np.asarray(frame, dtype=np.uint8)
        self._frames += 1
        if self.format == "mp4":
            if self._writer is None:
                import imageio.v2 as imageio

                self._writer = imageio.get_writer(self.path, fps=self.fps, codec="libx264",
                                                  macro_block_size=2)  # fmt: skip
            self._writer.append_data(frame)
            return
        from PIL import Image

        image = Image.fromarray(frame)
        if self._palette is None:
            self._palette = image.quantize(colors=128, method=Image.Quantize.FASTOCTREE)
        self._images.append(image.quantize(palette=self._palette, dither=Image.Dither.NONE))

    def close(self) -> str:
        """Finish the file (writing a held-back last frame); returns its path."""
        if self._held is not None:
            self._write(self._held())
            self._held = None
        if self._writer is not None:
            self._writer.close()
        elif self._images:
            first, *rest = self._images
            first.save(self.path, save_all=True, append_images=rest,
                       duration=round(1000 / self.fps), loop=0)  # fmt: skip
            self._images = []
        else:
            raise ValueError("no frame to write")
        return self.path
