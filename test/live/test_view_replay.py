"""``lander view BAG``: a recorded flight replayed in the student page's 3-D view (docs/live.md).

The records come from :mod:`lander_tools.live.replay` (checked on a synthetic bag whose attitude
is known in closed form); the page is the real one, served by the real command as a child
process, in headless Chromium, on a bag the real launcher recorded (`lander fly hover --speed 0
--duration 5 --record DIR`) and on the synthetic tumbling one.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tools.synth import write_flight_bag

import rosutil
from lander_ros.stamps import stamp_to_seconds
from lander_sim.physics.rotation import body_to_world
from lander_tools.bagio import read_bag
from lander_tools.live import replay

from .liveutil import console_errors, launch_chromium, wait_until

N_SYNTH = 41


def tumbling_bag(path: Path) -> np.ndarray:
    """A synthetic flight at a constant 500 m whose body turns about the world x axis from 0 to
    pi (the lander sits on the -y axis, so its z axis starts horizontal, passes the local vertical
    at a = pi/2 and ends horizontal again): tilt = |pi/2 - a| (z_B = (0, -sin a, cos a) against
    the vertical (0, -1, 0)). Returns the angles a."""
    t = np.linspace(0.0, 4.0, N_SYNTH)
    a = np.linspace(0.0, math.pi, N_SYNTH)
    q = np.column_stack([np.cos(a / 2), np.sin(a / 2), np.zeros_like(a), np.zeros_like(a)])  # core q (s, x, y, z)
    write_flight_bag(path, t, np.full_like(t, 500.0), np.zeros_like(t), q=q,
                     throttles=np.tile([0.0, 0.25, 0.5, 1.0], (N_SYNTH, 1)), meta={"scene": "hover"},
                     status_demand=np.where(t < 2.0, 500.0, 520.0))
    return a


def test_replay_records_are_the_bags_states_with_the_demand_in_force_and_the_attitude(tmp_path: Path) -> None:
    a = tumbling_bag(tmp_path / "tumble")
    rep = replay.load(tmp_path / "tumble")
    assert rep.scene == "hover" and rep.note == "" and len(rep.records) == N_SYNTH
    for rec, angle in zip(rep.records, a):
        assert rec["tilt"] == pytest.approx(abs(math.pi / 2 - angle), abs=1e-9)
        assert rec["demand_altitude"] == (500.0 if rec["t"] < 2.0 - 1e-9 else 520.0)
        assert len(rec["plumes_B"]) == 3  # the thruster at throttle 0 has no plume
    assert not any(rec["fixed_pivot"] for rec in rep.records)
    json.dumps(rep.page_json(), allow_nan=False)  # what the page gets is plain JSON
    # A rotor scene's body turns about a fixed pivot: the view draws its z axis track.
    write_flight_bag(tmp_path / "rotor", np.array([0.0, 0.1]), np.full(2, 500.0), np.zeros(2),
                     meta={"scene": "rotor-quaternion"})
    assert all(rec["fixed_pivot"] for rec in replay.load(tmp_path / "rotor").records)
    with pytest.raises(ValueError, match="not found"):
        replay.load(tmp_path / "missing")


def test_view_of_a_bag_that_is_not_one_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from lander_tools import cli

    (tmp_path / "empty").mkdir()
    assert cli.main(["view", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lander view: ") and len(err.strip().splitlines()) == 1, err


def start_view(bag: Path) -> tuple[rosutil.ChildProcess, str]:
    child = rosutil.ChildProcess(["-m", "lander_tools.cli", "view", str(bag), "--port", "0"], name="view")
    found = wait_until(lambda: re.search(r"on (http://127\.0\.0\.1:\d+/)", child.output())
                       or (child.returncode is not None and child.output() + " "), 60.0, "the page's URL")
    if isinstance(found, str):
        raise RuntimeError(f"lander view exited: {found}")
    return child, found.group(1)


@contextlib.contextmanager
def replay_page(bag: Path) -> Iterator[tuple[Any, list[str]]]:
    """``lander view bag`` in headless Chromium: the page once its replay holds the bag's records,
    and the list its console errors go to; browser and view closed afterwards."""
    from playwright.sync_api import sync_playwright

    view, url = start_view(bag)
    try:
        with sync_playwright() as pw:
            browser = launch_chromium(pw)
            try:
                page = browser.new_context(viewport={"width": 1400, "height": 1000}).new_page()
                errors = console_errors(page)
                page.goto(url)
                page.wait_for_function("window.replay && window.replay.records.length > 0", timeout=30_000)
                yield page, errors
            finally:
                browser.close()
    finally:
        view.close()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A 5 s hover recorded by the real launcher (lockstep, as fast as it goes)."""
    bag = tmp_path_factory.mktemp("view") / "hover5"
    fly = rosutil.ChildProcess(["-m", "lander_tools.cli", "fly", "hover", "--speed", "0", "--duration", "5",
                                "--record", str(bag), "--no-progress"], name="fly")
    try:
        wait_until(lambda: fly.returncode is not None, 180.0, "the recorded flight to end")
        assert fly.returncode == 0, fly.output()[-3000:]
    finally:
        fly.close()
    yield bag


def test_view_replays_a_recorded_flight_to_its_end(recorded: Path, tmp_path: Path) -> None:
    states = read_bag(recorded, ["/lander/state"]).topics["/lander/state"].messages
    t_end = stamp_to_seconds(states[-1].header.stamp)
    with replay_page(recorded) as (page, errors):
        assert page.evaluate("window.replay.records.length") == len(states)
        page.select_option("#replay-speed", "20")
        page.click("#play")
        page.wait_for_function("window.replay.index === window.replay.records.length - 1 && !window.replay.playing",
                               timeout=30_000)
        shown, drawn = page.evaluate("[window.liveStats.last, window.view3d.state()]")
        assert shown["t"] == pytest.approx(t_end, abs=1e-9) and drawn["t"] == shown["t"]
        assert drawn["trail"] == len(states)  # every state of the flight drawn in the trail
        np.testing.assert_allclose(drawn["position"], shown["position_S"], atol=1e-3)
        np.testing.assert_allclose(drawn["z_axis"], shown["up_S"], atol=1e-6)
        page.wait_for_timeout(300)  # let the graphs (10 Hz) draw the end for the picture
        shot = tmp_path / "view-replay.png"
        page.screenshot(path=str(shot))
        if os.environ.get("LANDER_DOCS_SCREENSHOT"):
            shutil.copy(shot, os.environ["LANDER_DOCS_SCREENSHOT"])
        # The slider goes back: the view shows the flight up to that state only.
        page.eval_on_selector("#replay-slider", "(s) => { s.value = '10'; s.dispatchEvent(new Event('input')); }")
        back = page.evaluate("[window.liveStats.last.t, window.view3d.state().trail]")
        assert back == [pytest.approx(stamp_to_seconds(states[10].header.stamp), abs=1e-9), 11]
        assert errors == []


def test_the_drawn_body_turns_with_the_recorded_attitude(tmp_path: Path) -> None:
    """On the tumbling bag the drawn body's z axis is the state's up_S at every state, and the
    picture of the view at a = 0 and at a = pi / 2 differs (same place, camera and trail: only the
    attitude changed)."""
    from PIL import Image

    tumbling_bag(tmp_path / "tumble")
    with replay_page(tmp_path / "tumble") as (page, errors):
        pictures = {}
        for i in range(N_SYNTH):
            page.eval_on_selector("#replay-slider", f"(s) => {{ s.value = '{i}'; s.dispatchEvent(new Event('input')); }}")
            rec, drawn = page.evaluate("[window.liveStats.last, window.view3d.state()]")
            np.testing.assert_allclose(drawn["z_axis"], rec["up_S"], atol=1e-6)
            if i in (0, N_SYNTH // 2):
                page.evaluate("() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
                png = page.locator("#view3d").screenshot()
                pictures[i] = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
        upright, turned = pictures[N_SYNTH // 2], pictures[0]
        h, w = upright.shape
        centre = (slice(h // 4, 3 * h // 4), slice(w // 4, 3 * w // 4))  # where the body is drawn
        changed = np.mean(np.abs(upright[centre] - turned[centre]) > 16)
        assert changed > 0.002, changed  # the body's pixels (~1 % of the centre) moved
        assert errors == []


def test_far_from_the_ground_the_view_shows_the_planet_and_the_orbit_at_scale(tmp_path: Path) -> None:
    """A descent from 150 km to 30 km (above the 20 km of PLANET_VIEW_ALTITUDE all along): the view
    draws the planet frame in km, the lander at its world position / 1000, every state in the orbit
    line, the body in its world attitude (z axis = q_WB applied to z)."""
    t = np.linspace(0.0, 600.0, 61)
    write_flight_bag(tmp_path / "high", t, 150e3 - 200.0 * t, np.full_like(t, -200.0), meta={"scene": "hover"})
    with replay_page(tmp_path / "high") as (page, errors):
        page.eval_on_selector("#replay-slider", "(s) => { s.value = s.max; s.dispatchEvent(new Event('input')); }")
        rec, drawn = page.evaluate("[window.liveStats.last, window.view3d.state()]")
        assert drawn["view"] == "planet" and rec["altitude"] == pytest.approx(30e3)
        np.testing.assert_allclose(drawn["position"], np.asarray(rec["position_W"]) * 1e-3, rtol=1e-6)
        x, y, z, w = rec["q_WB"]
        z_W = body_to_world(np.array([w, x, y, z]), np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(drawn["z_axis"], z_W, atol=1e-6)
        assert page.evaluate("window.view3d.orbit.n") == len(t)
        assert errors == []
