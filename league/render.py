"""Pictures of tracks and races.

`render_frame` draws a frame with numpy alone (fast enough for an environment's
``render_mode="rgb_array"``); `save_track_png` and `animate_replay` draw with matplotlib, in the
spirit of the thesis' race figure, and save without a display (Agg canvas).
"""
from __future__ import annotations

import math
import os
import sys
import weakref
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from league.constants import CELLS_PER_UNIT, GRID, OUTCOME_TEXT

DOWNSAMPLE = 2  # map cells per frame pixel: a full map is 650 px wide
MARGIN = 12  # px around the track's bounding box
CAR_RADIUS = 4  # px
HEADING_LENGTH = 10  # px, the tick showing where a car points
TRAIL_HALF_WIDTH = 1  # px each side of the trail's centre line

OFF_ROAD = (226, 236, 218)  # pale green
ROAD = (168, 168, 168)  # grey
OBSTACLE = (30, 30, 30)  # near black: distinct from every car colour
HEADING_TICK = (20, 20, 20)
START_COLOR = "white"  # the start line and arrow of the track pictures
START_ARROW = 0.1  # world units, the arrow's length
# matplotlib's "tab10" palette: the colours of the cars, in order.
CAR_COLORS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
              (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]

FRAME_STRIDE = 4  # simulation steps per animation frame
ANIMATION_FPS = 15  # with stride 4 at 25 steps/s: about 2.4 x real time
MAX_FRAMES = 400  # longer races are shown with a coarser stride (memory and time of the GIF)


class RenderError(RuntimeError):
    """A picture or animation cannot be produced (missing writer, no display...)."""


# --------------------------------------------------------------------------- numpy frames


FRAME_SIZE = GRID // DOWNSAMPLE  # px per side of every frame: the whole [-1.3, 1.3]^2 world
FRAME_SHAPE = (FRAME_SIZE, FRAME_SIZE, 3)  # the envs declare it in metadata["render_frame_shape"]


@dataclass(frozen=True)
class TrackImage:
    """A track's background over the whole world at 1 px = 2 map cells, and its picture crop.

    Frames use the whole image, so every track gives frames of the same size and scale (video
    recorders and pixel observations need a fixed shape); pictures show only ``crop``, the
    track's bounding box with a margin.
    """

    rgb: np.ndarray  # FRAME_SHAPE uint8
    crop: tuple[slice, slice]  # (rows, cols) of the track's bounding box and margin

    @staticmethod
    def to_pixels(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World coordinates -> (row, col) as floats in the frame (y axis up)."""
        col = (np.asarray(x) * CELLS_PER_UNIT + GRID / 2) / DOWNSAMPLE
        row = (GRID / 2 - np.asarray(y) * CELLS_PER_UNIT) / DOWNSAMPLE
        return row, col

    def cropped(self) -> np.ndarray:
        return self.rgb[self.crop]

    def extent(self) -> tuple[float, float, float, float]:
        """(left, right, bottom, top) of the crop in world units, for matplotlib's imshow."""
        rows, cols = self.crop
        scale = DOWNSAMPLE / CELLS_PER_UNIT
        left = (cols.start * DOWNSAMPLE - GRID / 2) / CELLS_PER_UNIT
        top = (GRID / 2 - rows.start * DOWNSAMPLE) / CELLS_PER_UNIT
        return left, left + (cols.stop - cols.start) * scale, top - (rows.stop - rows.start) * scale, top


_track_images: weakref.WeakKeyDictionary[Any, TrackImage] = weakref.WeakKeyDictionary()


def track_image(track: Any) -> TrackImage:
    """The track's background image (cached per track: an env renders the same one every frame)."""
    cached = _track_images.get(track)
    if cached is None:
        cached = _track_images[track] = _draw_track_image(track)
    return cached


def _draw_track_image(track: Any) -> TrackImage:
    obstacles = np.asarray(track.obstacle_cells, dtype=bool)
    road = np.asarray(track.valid, dtype=bool) | obstacles
    road_px, obstacle_px = _downsample(road), _downsample(obstacles)
    rows, cols = np.nonzero(road_px)
    if rows.size == 0:
        raise RenderError("the track has no road cells to draw")
    crop = (slice(max(rows.min() - MARGIN, 0), min(rows.max() + MARGIN + 1, FRAME_SIZE)),
            slice(max(cols.min() - MARGIN, 0), min(cols.max() + MARGIN + 1, FRAME_SIZE)))
    rgb = blank_frame()
    rgb[road_px] = ROAD
    rgb[obstacle_px] = OBSTACLE
    return TrackImage(rgb, crop)


def blank_frame() -> np.ndarray:
    """A frame of FRAME_SHAPE with nothing but the field (what an env renders before its first reset)."""
    frame = np.empty(FRAME_SHAPE, dtype=np.uint8)
    frame[...] = OFF_ROAD
    return frame


def _downsample(grid: np.ndarray) -> np.ndarray:
    """(1300, 1300) map indexed [i=x, j=y] -> (650, 650) image indexed [row, col], y axis up."""
    n = grid.shape[0] // DOWNSAMPLE
    pooled = grid[: n * DOWNSAMPLE, : n * DOWNSAMPLE].reshape(n, DOWNSAMPLE, n, DOWNSAMPLE).any(axis=(1, 3))
    return pooled.T[::-1]


def render_frame(track: Any, xs: Sequence[float], ys: Sequence[float], headings: Sequence[float],
                 trails: Sequence[np.ndarray] | None = None, colors: Sequence[tuple] | None = None) -> np.ndarray:
    """Draw a frame: the track (road, obstacles), each car's trail and a marker with its heading.

    Args:
        track: a ``league.track.Track``.
        xs, ys, headings: per car, position (world units) and heading (rad).
        trails: per car, an (k, 2) array of past positions (or None / empty for no trail).
        colors: per car, an RGB triple (0-255); default the "tab10" palette, cycled.

    Returns:
        uint8 array of FRAME_SHAPE (650, 650, 3): the whole world, whatever the track, at
        1 px = 2 map cells. Pure numpy: a frame costs well under a millisecond per car.
    """
    image = track_image(track)
    frame = image.rgb.copy()
    xs, ys, headings = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (xs, ys, headings))
    colors = ([tuple(c) for c in colors] if colors is not None
              else [CAR_COLORS[i % len(CAR_COLORS)] for i in range(len(xs))])
    for i, trail in enumerate(trails or []):
        if trail is not None and len(trail) > 1:
            trail = np.asarray(trail, dtype=np.float64)
            _draw_polyline(frame, *image.to_pixels(trail[:, 0], trail[:, 1]), colors[i % len(colors)])
    for i in range(len(xs)):
        row, col = image.to_pixels(xs[i], ys[i])
        _draw_heading(frame, float(row), float(col), float(headings[i]))
        _draw_disc(frame, float(row), float(col), colors[i % len(colors)])
    return frame


class EnvRendering:
    """The envs' rendering (MicroRacerEnv, MicroRacerParallelEnv, MicroRacerVectorEnv): the
    render-mode check, `render()` and `close()`, drawing what the env's `scene()` gives.

    `render()` returns a frame of FRAME_SHAPE ("rgb_array"), or shows it in a matplotlib window
    ("human"); before the first reset it is a blank frame (wrappers render then to learn the shape).
    """

    metadata: dict
    render_mode: str | None = None
    _window: Any = None
    maker = "gymnasium.make"  # what the warning of `render()` without a render mode tells to call

    def check_render_mode(self, render_mode: str | None) -> str | None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        return render_mode

    def scene(self) -> tuple[Any, Any, Any, Any, list] | None:
        """(track, xs, ys, headings, trails) to draw, or None before the first reset."""
        raise NotImplementedError

    def render(self):
        if self.render_mode is None:
            from gymnasium import logger

            logger.warn(f'render() needs a render_mode: {self.maker}(..., render_mode="rgb_array")')
            return None
        scene = self.scene()
        frame = blank_frame() if scene is None else render_frame(*scene)
        if self.render_mode == "rgb_array":
            return frame
        self._window = show_frame(frame, self._window)
        return None

    def close(self, **kwargs):
        if self._window is not None:
            close_window(self._window)
            self._window = None
        super().close(**kwargs)


def _draw_polyline(frame: np.ndarray, rows: np.ndarray, cols: np.ndarray, color: tuple) -> None:
    """Densify the polyline to half-pixel spacing and paint a band TRAIL_HALF_WIDTH px wide."""
    lengths = np.hypot(np.diff(rows), np.diff(cols))
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    samples = np.arange(0.0, arc[-1] + 0.5, 0.5)
    r = np.rint(np.interp(samples, arc, rows)).astype(np.int64)
    c = np.rint(np.interp(samples, arc, cols)).astype(np.int64)
    offsets = np.arange(-TRAIL_HALF_WIDTH, TRAIL_HALF_WIDTH + 1)
    _paint(frame, (r[:, None] + offsets[None, :]).ravel(), np.repeat(c, offsets.size), color)
    _paint(frame, np.repeat(r, offsets.size), (c[:, None] + offsets[None, :]).ravel(), color)


_DISC = (np.argwhere(np.hypot(*np.mgrid[-CAR_RADIUS:CAR_RADIUS + 1, -CAR_RADIUS:CAR_RADIUS + 1]) <= CAR_RADIUS + 0.3)
         - CAR_RADIUS)


def _draw_disc(frame: np.ndarray, row: float, col: float, color: tuple) -> None:
    _paint(frame, int(round(row)) + _DISC[:, 0], int(round(col)) + _DISC[:, 1], color)


def _draw_heading(frame: np.ndarray, row: float, col: float, heading: float) -> None:
    t = np.linspace(0, HEADING_LENGTH, 2 * HEADING_LENGTH + 1)
    rows = np.rint(row - t * np.sin(heading)).astype(np.int64)  # image rows grow downwards
    cols = np.rint(col + t * np.cos(heading)).astype(np.int64)
    _paint(frame, rows, cols, HEADING_TICK)


def _paint(frame: np.ndarray, rows: np.ndarray, cols: np.ndarray, color: tuple) -> None:
    inside = (rows >= 0) & (rows < frame.shape[0]) & (cols >= 0) & (cols < frame.shape[1])
    frame[rows[inside], cols[inside]] = color


# --------------------------------------------------------------------------- live window (env "human" mode)


def show_frame(frame: np.ndarray, window: Any = None) -> Any:
    """Show a frame in a matplotlib window, reusing ``window`` (the value this returned last time)."""
    import matplotlib.pyplot as plt

    if window is None or not plt.fignum_exists(window[0].number):
        figure = plt.figure("MicroRacer", figsize=(6.5, 6.5))
        axes = figure.add_axes((0, 0, 1, 1))
        axes.set_axis_off()
        window = (figure, axes.imshow(frame, interpolation="nearest"))
        plt.show(block=False)
    figure, picture = window
    if picture.get_array().shape != frame.shape:
        picture.set_extent((-0.5, frame.shape[1] - 0.5, frame.shape[0] - 0.5, -0.5))
    picture.set_data(frame)
    figure.canvas.draw_idle()
    plt.pause(0.001)
    return window


def close_window(window: Any) -> None:
    import matplotlib.pyplot as plt

    plt.close(window[0])


# --------------------------------------------------------------------------- matplotlib pictures


def _agg_figure(figsize: tuple[float, float], dpi: int = 100) -> Any:
    """A figure on an Agg canvas: drawing and saving never need a display or pyplot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(figure)
    return figure


def _draw_track(axes: Any, track: Any) -> TrackImage:
    image = track_image(track)
    axes.imshow(image.cropped(), extent=image.extent(), interpolation="antialiased", origin="upper")
    _draw_start(axes, track)
    axes.set_aspect("equal")
    axes.set_axis_off()
    return image


def _draw_start(axes: Any, track: Any) -> None:
    """A line across the road and an arrow the way the race goes, white edged in black: unlike the
    near-black obstacles (a small black arrow and square looked like one more obstacle)."""
    x, y = track.start_position
    along = np.array([np.cos(track.start_heading), np.sin(track.start_heading)])
    across = np.array([-along[1], along[0]]) * track.width * 0.6
    line = ([x - across[0], x + across[0]], [y - across[1], y + across[1]])
    axes.plot(*line, color="black", lw=4.5, solid_capstyle="butt")
    axes.plot(*line, color=START_COLOR, lw=3, solid_capstyle="butt")
    axes.annotate("", xy=(x, y) + START_ARROW * along, xytext=(x, y),
                  arrowprops={"arrowstyle": "simple", "fc": START_COLOR, "ec": "black", "lw": 0.8,
                              "mutation_scale": 20})


def _track_picture(figure: Any, track: Any, title: str | None) -> None:
    """The track with a title and a legend of what is drawn."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    _draw_track(figure.add_axes((0.02, 0.08, 0.96, 0.84 if title else 0.9)), track)
    if title:
        figure.suptitle(title)
    handles = [Patch(fc=np.array(ROAD) / 255, label="road"), Patch(fc=np.array(OBSTACLE) / 255, label="obstacle"),
               Line2D([], [], ls="none", marker=">", ms=10, mfc=START_COLOR, mec="black",
                      label="start, and the way to race")]
    figure.legend(handles=handles, loc="lower center", ncol=3, frameon=False)


def save_track_png(track: Any, path: str | os.PathLike, title: str | None = None, dpi: int = 100) -> Path:
    """Save a picture of a track (road, obstacles, start and direction, a legend) as PNG, without a display."""
    figure = _agg_figure((6.5, 6.5))
    _track_picture(figure, track, title)
    path = Path(path)
    figure.savefig(path, dpi=dpi)
    return path


def show_track(track: Any, title: str | None = None) -> None:
    """Show a picture of a track in a window (needs a display)."""
    require_display()
    import matplotlib.pyplot as plt

    _track_picture(plt.figure("MicroRacer track", figsize=(6.5, 6.5)), track, title)
    plt.show()


def ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def action_text(acc: float, turn: float, speed: float) -> str:
    """The thesis' legend line: "accelerating 0.52 | right 0.31 | speed 0.27" (positive turn = right)."""
    throttle = f"accelerating {acc:.2f}" if acc >= 0 else f"braking {-acc:.2f}"
    steering = "straight" if turn == 0 else (f"right {turn:.2f}" if turn > 0 else f"left {-turn:.2f}")
    return f"{throttle} | {steering} | speed {speed:.2f}"


def final_text(row: dict) -> str:
    """A car's line once it stopped: its place and time, or why it stopped."""
    if row["outcome"] == "finished":
        return f"{ordinal(row['position'])}  {row['time']:.1f} s"
    if row["outcome"] == "dnf":
        return _shorten(f"DNF: {row.get('reason') or OUTCOME_TEXT['dnf']}", 60)
    return OUTCOME_TEXT.get(row["outcome"], row["outcome"])


def _shorten(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


class RaceAnimation:
    """The thesis' race figure for a replay: track, trails, car markers and a per-car legend.

    ``draw(step)`` updates the moving artists in place for a simulation step (no axes rebuilt);
    ``frames(steps)`` renders them over a static background drawn once, for saving.
    """

    def __init__(self, replay: dict, figure: Any):
        from league.track import Track

        self.replay = replay
        self.figure = figure
        self.cars = replay["cars"]
        self.steps = [len(car["x"]) - 1 for car in self.cars]
        self.total_steps = max(self.steps)
        self.rows = {row["car"]: row for row in replay["classification"]}
        n = len(self.cars)
        legend_width = 0.36
        self.axes = figure.add_axes((0.01, 0.02, 0.98 - legend_width, 0.9))
        _draw_track(self.axes, Track.from_dict(replay["track"]))
        colors = [np.array(CAR_COLORS[i % len(CAR_COLORS)]) / 255 for i in range(n)]
        self.trails = [self.axes.plot([], [], color=c, lw=1.6, solid_capstyle="round")[0] for c in colors]
        self.markers = [self.axes.plot([], [], "o", color=c, markersize=6, markeredgecolor="black",
                                       markeredgewidth=0.6)[0] for c in colors]
        self.title = figure.text(0.02, 0.965, "", fontsize=11, weight="bold", va="center")
        self.status = self._legend(colors, legend_width)

    def _legend(self, colors: list, width: float) -> list:
        top, spacing = 0.9, min(0.085, 0.88 / max(len(self.cars), 1))
        status = []
        for i, (car, color) in enumerate(zip(self.replay["names"], colors)):
            y = top - i * spacing
            self.figure.text(1 - width + 0.01, y, "\u25cf", color=color, fontsize=13, va="center")
            self.figure.text(1 - width + 0.04, y, _shorten(car, 34), fontsize=9, weight="bold", va="center")
            status.append(self.figure.text(1 - width + 0.04, y - spacing * 0.38, "", fontsize=8, va="center",
                                           family="monospace"))
        return status

    def draw(self, step: int) -> list:
        """Update every moving artist for simulation ``step``; return them."""
        for i, car in enumerate(self.cars):
            last = min(step, self.steps[i])
            self.trails[i].set_data(car["x"][: last + 1], car["y"][: last + 1])
            self.markers[i].set_data([car["x"][last]], [car["y"][last]])
            if step < self.steps[i]:
                self.status[i].set_text(action_text(car["acc"][step], car["turn"][step], car["speed"][step]))
            else:
                self.status[i].set_text(final_text(self.rows[f"car_{i}"]))
        seconds = min(step, self.total_steps) * self.replay["tstep"]
        self.title.set_text(f"MicroRacer race, seed {self.replay['seed']}   t = {seconds:5.1f} s")
        return self.trails + self.markers + self.status + [self.title]

    def frame_steps(self, stride: int = FRAME_STRIDE) -> list[int]:
        """The steps shown: every ``stride``-th (coarser if the race is long), and always the last one."""
        stride = max(stride, math.ceil(self.total_steps / MAX_FRAMES))
        steps = list(range(0, self.total_steps + 1, stride))
        if steps[-1] != self.total_steps:
            steps.append(self.total_steps)
        return steps

    def frames(self, steps: Sequence[int]) -> Iterator[np.ndarray]:
        """RGB frames (H, W, 3) for the given steps, drawn on the Agg canvas.

        The static part (track, names) is drawn once; each frame restores it and draws only the
        moving artists, which makes a frame several times cheaper than a full figure draw.
        """
        canvas = self.figure.canvas
        moving = self.draw(0)
        for artist in moving:
            artist.set_visible(False)
        canvas.draw()
        background = canvas.copy_from_bbox(self.figure.bbox)
        for artist in moving:
            artist.set_visible(True)
        for step in steps:
            canvas.restore_region(background)
            for artist in self.draw(step):
                self.figure.draw_artist(artist)
            yield np.asarray(canvas.buffer_rgba())[..., :3].copy()


def animate_replay(replay: dict, show: bool = False, save: str | os.PathLike | None = None,
                   stride: int = FRAME_STRIDE, fps: int = ANIMATION_FPS, dpi: int = 80) -> Any:
    """Animate a race replay (``league.evaluation.race(...).replay`` or ``load_replay(path)``).

    Args:
        replay: the replay dict.
        show: open a window and play the race (needs a display).
        save: write the animation to a ``.gif`` (Pillow) or ``.mp4`` (ffmpeg) file; this uses an
            Agg canvas and works without a display.
        stride: simulation steps per frame (4: a 25 steps/s race at ``fps`` 15 plays at ~2.4x).
        fps: frames per second of the saved or shown animation.
        dpi: resolution of the saved file (the figure is 10 x 6.5 inches).

    Returns:
        The saved file's Path, or the matplotlib FuncAnimation when shown.

    Raises:
        RenderError: unknown file type, ffmpeg missing for MP4, or no display for ``show``.
    """
    if not show and save is None:
        raise RenderError("nothing to do: pass show=True or save='race.gif'")
    path = None
    if save is not None:
        path = _save_animation(replay, Path(save), stride, fps, dpi)
    if show:
        return _show_animation(replay, stride, fps)
    return path


def check_animation_path(path: str | os.PathLike) -> str | None:
    """Raise RenderError unless an animation can be saved there; return the ffmpeg to use (None: GIF)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4", ".m4v", ".mov"):
        raise RenderError(f"cannot save an animation as {path.name}: use a .gif or .mp4 file name")
    return None if suffix == ".gif" else _ffmpeg()


def _save_animation(replay: dict, path: Path, stride: int, fps: int, dpi: int) -> Path:
    ffmpeg = check_animation_path(path)
    animation = RaceAnimation(replay, _agg_figure((10, 6.5), dpi))
    steps = animation.frame_steps(stride)
    if ffmpeg is None:
        _write_gif(path, animation, steps, fps)
    else:
        _write_mp4(path, animation, steps, fps, ffmpeg)
    return path


def _write_gif(path: Path, animation: RaceAnimation, steps: list[int], fps: int) -> None:
    """GIF through Pillow, every frame mapped to one palette taken from the last (fullest) frame."""
    from PIL import Image

    last = next(animation.frames([steps[-1]]))
    palette = Image.fromarray(last).quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(frame).quantize(palette=palette, dither=Image.Dither.NONE)
              for frame in animation.frames(steps)]
    durations = [round(1000 / fps)] * (len(images) - 1) + [2000]  # hold the final standings
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations, loop=0, disposal=1)


def _ffmpeg() -> str:
    import shutil

    from matplotlib import rcParams

    ffmpeg = shutil.which(rcParams["animation.ffmpeg_path"]) or shutil.which("ffmpeg")
    if ffmpeg is None:
        try:  # the binary the video extra installs (pip install 'microracer-league[video]')
            import imageio_ffmpeg

            ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
        except (ImportError, RuntimeError):
            raise RenderError("saving MP4 needs ffmpeg: pip install 'microracer-league[video]' (or 'apt install "
                              "ffmpeg'); or save a .gif instead") from None
    return ffmpeg


def _write_mp4(path: Path, animation: RaceAnimation, steps: list[int], fps: int, ffmpeg: str) -> None:
    """H.264 MP4: raw RGB frames piped to ffmpeg."""
    import subprocess

    width, height = (int(v) for v in animation.figure.canvas.get_width_height())
    command = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}",
               "-r", str(fps), "-i", "-", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264",
               "-pix_fmt", "yuv420p", str(path)]
    with subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as process:
        try:
            for frame in animation.frames(steps):
                process.stdin.write(frame.tobytes())
            process.stdin.close()
        except BrokenPipeError:
            pass
        error = process.stderr.read().decode(errors="replace")
    if process.returncode != 0:
        raise RenderError(f"ffmpeg failed to write {path.name}: {error.strip()[-300:]}")


def _show_animation(replay: dict, stride: int, fps: int) -> Any:
    require_display()
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    figure = plt.figure("MicroRacer race", figsize=(10, 6.5))
    race_animation = RaceAnimation(replay, figure)
    player = FuncAnimation(figure, race_animation.draw, frames=race_animation.frame_steps(stride),
                           interval=1000 / fps, blit=False, repeat=False)
    plt.show()
    return player


def require_display() -> None:
    """Raise RenderError when a window cannot be opened (no X/Wayland display, or a non-GUI backend)."""
    headless_linux = sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    backend = os.environ.get("MPLBACKEND", "").lower()
    if headless_linux or backend in ("agg", "pdf", "svg", "ps", "cairo", "template"):
        raise RenderError("no display available to show a window; save to a file instead (e.g. --save race.gif)")
