"""league.render: numpy frames, track pictures, race animations (without a display), MP4 through
the video extra's ffmpeg, and the env's "human" window on a virtual X display (Xvfb)."""
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import league
from league import render
from league.evaluation import race, save_replay

from .layout import REPO


@pytest.fixture(scope="module")
def track():
    env = league.MicroRacerEnv()
    env.reset(seed=5)
    return env.track


@pytest.fixture(scope="module")
def small_race():
    return race(["heuristic", "heuristic-lidar", "heuristic"], seed=1, names=["a", "b", "c"])


def pixel_of(track, x, y):
    row, col = render.track_image(track).to_pixels(x, y)
    return int(round(float(row))), int(round(float(col)))


# --------------------------------------------------------------------------- numpy frames


def test_frame_is_the_whole_world_at_a_fixed_size(track):
    frame = render.render_frame(track, [], [], [], [])
    assert frame.dtype == np.uint8 and frame.shape == render.FRAME_SHAPE == (650, 650, 3)
    road = np.asarray(track.valid).sum() / render.DOWNSAMPLE**2
    assert (frame == render.ROAD).all(axis=2).sum() == pytest.approx(road, rel=0.15)
    assert (frame == render.OBSTACLE).all(axis=2).any()
    for edge in (frame[0], frame[-1], frame[:, 0], frame[:, -1]):  # no track reaches the world's edge
        assert (edge == render.OFF_ROAD).all()
    other = league.generate_track(np.random.default_rng(6))
    assert render.render_frame(other, [], [], []).shape == frame.shape


def test_pictures_crop_the_frame_to_the_track(track):
    image = render.track_image(track)
    picture = image.cropped()
    assert picture.shape[0] < render.FRAME_SIZE and picture.shape[1] < render.FRAME_SIZE
    for edge in (picture[0], picture[-1], picture[:, 0], picture[:, -1]):  # a margin of field around the road
        assert (edge == render.OFF_ROAD).all()
    left, right, bottom, top = image.extent()
    assert (right - left) * 250 == pytest.approx(picture.shape[1])
    assert (top - bottom) * 250 == pytest.approx(picture.shape[0])


def test_start_is_on_the_road_and_obstacles_where_the_map_says(track):
    frame = render.render_frame(track, [], [], [], [])
    assert tuple(frame[pixel_of(track, *track.start_position)]) == render.ROAD
    i, j = np.argwhere(track.obstacle_cells)[len(np.argwhere(track.obstacle_cells)) // 2]
    x, y = (i - 650 + 0.5) / 500, (j - 650 + 0.5) / 500
    row, col = pixel_of(track, x, y)
    patch = frame[row - 1:row + 2, col - 1:col + 2]
    assert (patch == render.OBSTACLE).all(axis=2).any()


def test_cars_and_trails_are_drawn_in_their_colours(track):
    x0, y0 = track.start_position
    theta = np.linspace(0, -0.3, 40)
    trail = track.midline(np.mod(theta, 2 * np.pi))
    colors = [(255, 0, 255), (0, 255, 255)]
    frame = render.render_frame(track, [trail[-1, 0], x0], [trail[-1, 1], y0], [0.0, track.start_heading],
                                [trail, None], colors=colors)
    assert tuple(frame[pixel_of(track, *trail[-1])]) == colors[0]
    assert tuple(frame[pixel_of(track, x0, y0)]) == colors[1]
    middle = trail[20]
    assert tuple(frame[pixel_of(track, *middle)]) == colors[0]  # the trail between start and car
    magenta = (frame == colors[0]).all(axis=2).sum()
    assert magenta > 100  # a line, not just the marker


def test_the_background_is_drawn_once_per_track_and_frames_do_not_change_it(track):
    background = render.track_image(track).rgb.copy()
    trails = [track.midline(np.linspace(0, 2 * np.pi * k / 10, 600)) for k in range(1, 11)]
    xs, ys = [t[-1, 0] for t in trails], [t[-1, 1] for t in trails]
    frame = render.render_frame(track, xs, ys, np.zeros(10), trails)  # its speed: benchmarks/bench_simulator.py
    assert render.track_image(track) is render.track_image(track)
    np.testing.assert_array_equal(render.track_image(track).rgb, background)
    assert (frame != background).any(axis=2).sum() > 1000  # 10 trails drawn


def test_env_rgb_array_uses_the_frame(track):
    env = league.MicroRacerEnv(render_mode="rgb_array")
    env.reset(seed=5)
    for _ in range(10):
        env.step(np.array([0.5, 0.0], dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == render.track_image(env.track).rgb.shape


ENVS = {"single": lambda **kw: league.MicroRacerEnv(**kw),
        "parallel": lambda **kw: league.make_parallel_env(n_cars=2, **kw),
        "vector": lambda **kw: league.make_vector_env(num_envs=2, **kw)}


@pytest.mark.parametrize("kind", ENVS)
def test_the_three_envs_render_alike(kind):
    """render.EnvRendering: the same render-mode check, blank frame before a reset, frame of the
    first car's track after it, and a warning that says how to ask for frames."""
    with pytest.raises(ValueError, match="render_mode must be one of .* or None, got 'bogus'"):
        ENVS[kind](render_mode="bogus")
    env = ENVS[kind](render_mode="rgb_array")
    assert (env.render() == render.blank_frame()).all()
    env.reset(seed=5)
    track = env.track if kind != "vector" else env.tracks[0]
    frame = env.render()
    assert frame.shape == render.FRAME_SHAPE and (frame != render.track_image(track).rgb).any()  # the car
    env.close()
    maker = {"single": "gymnasium.make", "parallel": "league.make_parallel_env", "vector": "league.make_vector_env"}
    with pytest.warns(UserWarning, match=f"render\\(\\) needs a render_mode: {maker[kind]}\\(..., render_mode="):
        assert ENVS[kind]().render() is None


# --------------------------------------------------------------------------- pictures and animations


def test_track_png(track, tmp_path):
    path = render.save_track_png(track, tmp_path / "track.png", title="seed 5")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size == (650, 650)


def test_track_picture_has_a_legend_and_a_white_start_unlike_the_dark_obstacles(track):
    figure = render._agg_figure((6.5, 6.5))
    render._track_picture(figure, track, "seed 5")
    assert ([text.get_text() for text in figure.legends[0].get_texts()]
            == ["road", "obstacle", "start, and the way to race"])
    figure.canvas.draw()
    rgb = np.asarray(figure.canvas.buffer_rgba())[..., :3]
    col, up = figure.axes[0].transData.transform(track.start_position)
    row, col = round(rgb.shape[0] - up), round(col)
    around_start = rgb[row - 3:row + 4, col - 3:col + 4]
    assert (around_start == 255).all(axis=2).any(), "the start is not drawn in white (obstacles are near-black)"


@pytest.mark.parametrize("acc, turn, speed, text", [
    (0.523, 0.31, 0.271, "accelerating 0.52 | right 0.31 | speed 0.27"),
    (-0.2, -0.5, 0.3, "braking 0.20 | left 0.50 | speed 0.30"),
    (0.0, 0.0, 0.1, "accelerating 0.00 | straight | speed 0.10"),
])
def test_action_text(acc, turn, speed, text):
    assert render.action_text(acc, turn, speed) == text


def test_ordinals():
    assert [render.ordinal(n) for n in (1, 2, 3, 4, 11, 12, 13, 21, 22, 101, 111)] == [
        "1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "101st", "111th"]


def test_legend_shows_actions_then_places_or_reasons(small_race):
    replay = small_race.replay
    animation = render.RaceAnimation(replay, render._agg_figure((10, 6.5), 60))
    animation.draw(10)
    car = replay["cars"][0]
    assert animation.status[0].get_text() == render.action_text(car["acc"][10], car["turn"][10], car["speed"][10])
    animation.draw(animation.total_steps)
    for i, row in enumerate(r for r in sorted(replay["classification"], key=lambda r: r["car"])):
        expected = (f"{render.ordinal(row['position'])}  {row['time']:.1f} s" if row["outcome"] == "finished"
                    else "off road")
        assert animation.status[i].get_text() == expected


def test_legend_explains_why_a_car_stopped():
    for outcome, text in [("off_road", "off road"), ("wrong_direction", "wrong direction"), ("too_slow", "too slow")]:
        assert render.final_text({"outcome": outcome, "position": 3, "time": 2.0}) == text
    assert render.final_text({"outcome": "dnf", "reason": "the model returned NaN"}) == "DNF: the model returned NaN"


def test_gif_has_every_frame_and_ends_on_the_result(small_race, tmp_path):
    path = render.animate_replay(small_race.replay, save=tmp_path / "race.gif")
    animation = render.RaceAnimation(small_race.replay, render._agg_figure((10, 6.5), 80))
    with Image.open(path) as gif:
        assert gif.n_frames == len(animation.frame_steps())
        assert gif.size == (800, 520)
    assert animation.frame_steps()[-1] == max(len(c["x"]) - 1 for c in small_race.replay["cars"])


def test_long_races_are_subsampled_to_a_bounded_number_of_frames(small_race):
    animation = render.RaceAnimation(small_race.replay, render._agg_figure((10, 6.5), 60))
    animation.total_steps = 4000
    assert len(animation.frame_steps()) <= render.MAX_FRAMES + 1


def test_saving_errors_are_clear(small_race, tmp_path, monkeypatch):
    with pytest.raises(render.RenderError, match="use a .gif or .mp4"):
        render.animate_replay(small_race.replay, save=tmp_path / "race.avi")
    monkeypatch.setenv("PATH", str(tmp_path))  # no ffmpeg anywhere
    monkeypatch.setitem(__import__("matplotlib").rcParams, "animation.ffmpeg_path", "ffmpeg")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # nor the video extra
    with pytest.raises(render.RenderError, match="needs ffmpeg"):
        render.animate_replay(small_race.replay, save=tmp_path / "race.mp4")


def test_league_replay_saves_an_mp4_with_every_frame_through_the_video_extras_ffmpeg(small_race, tmp_path):
    """`league replay --save race.mp4` with no ffmpeg on the PATH: imageio-ffmpeg's binary writes
    it; imageio reads back one frame per animation frame."""
    imageio = pytest.importorskip("imageio.v3", reason="counting MP4 frames needs imageio (the test extra)")
    replay = save_replay(small_race, tmp_path / "race.json")
    env = {**os.environ, "PATH": os.path.dirname(sys.executable), "PYTHONPATH": str(REPO), "MPLBACKEND": "agg"}
    done = subprocess.run([sys.executable, "-m", "league.cli", "replay", str(replay),
                           "--save", str(tmp_path / "race.mp4")],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert shutil.which("ffmpeg", path=env["PATH"]) is None  # the extra's binary, not the system's
    frames = imageio.imread(tmp_path / "race.mp4", plugin="FFMPEG", index=None)
    animation = render.RaceAnimation(small_race.replay, render._agg_figure((10, 6.5), 80))
    assert frames.shape == (len(animation.frame_steps()), 520, 800, 3)
    assert frames[0].std() > 10 and np.abs(frames[-1].astype(int) - frames[0]).mean() > 0.5  # drawn, and moving


HUMAN_SCRIPT = """
import numpy as np, matplotlib.pyplot as plt, league
from league.agents import load_agent
env, driver = league.MicroRacerEnv(render_mode="human"), load_agent("heuristic")
obs, _ = env.reset(seed=3)
for _ in range(15):
    obs, *_ = env.step(driver(obs[None])[0])
figure = plt.figure("MicroRacer")
figure.canvas.draw()
pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]
window = figure.canvas.manager.window
frame = np.asarray(figure.axes[0].images[0].get_array())  # what the env drew last
# the window's pixels, sampled back to the frame's size (the display's DPI scales the window)
rows, cols = (((np.arange(n) + 0.5) * m / n).astype(int) for n, m in zip(frame.shape[:2], pixels.shape[:2]))
same = np.mean(np.all(pixels[rows][:, cols] == frame, axis=-1))
print(type(figure.canvas).__name__, bool(window.winfo_ismapped()), len(plt.get_fignums()), f"{same:.4f}",
      len(np.unique(frame.reshape(-1, 3), axis=0)))
env.close()
"""


@pytest.fixture
def x_display():
    """A virtual X display of our own (Debian: apt-get install xvfb); its DISPLAY value."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("the human render mode is tested on a virtual display: apt-get install xvfb")
    read, write = os.pipe()  # Xvfb picks a free display number and writes it here
    server = subprocess.Popen([xvfb, "-displayfd", str(write), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                              pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()
    assert server.poll() is None and number, "Xvfb did not start"
    try:
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=10)


def test_human_mode_draws_the_race_in_a_window(x_display):
    env = {**os.environ, "DISPLAY": x_display, "MPLBACKEND": "TkAgg", "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, "-c", HUMAN_SCRIPT], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    canvas, mapped, windows, same, colours = done.stdout.split()
    assert (canvas, mapped, windows) == ("FigureCanvasTkAgg", "True", "1")  # one real window, on the screen
    assert float(same) > 0.95 and int(colours) >= 4  # it shows the env's frame (but where pixels are scaled)


def test_showing_without_a_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(render.sys, "platform", "linux")
    with pytest.raises(render.RenderError, match="no display"):
        render.require_display()
