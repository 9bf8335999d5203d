"""experiments/page.py: a run folder's report.html is self-contained (every figure and video
embedded), says the verdict, and renders in a real headless browser: a screenshot that is
not blank, every video loaded with the frame size it was written with, every image decoded.

The browser test needs Debian's chromium (``.ci/run`` installs it) and playwright; it is
skipped without them unless MJX_SURROGATE_REQUIRE_BROWSER is set (as CI sets it)."""

import base64
import json
import os
import re
import shutil

import numpy as np
import pytest

from experiments import page
from mjx_surrogate.runs import video

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture
def folder(tmp_path):
    """A run folder as an mpc run leaves it: metrics, config, a table, a figure, a video and
    its still."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = np.zeros((12, 48, 64, 3), np.uint8)
    for i, f in enumerate(frames):  # a bright square moving right
        f[16:32, 4 * i : 4 * i + 16] = 255
    video.write_mp4(str(tmp_path / "optimum.mp4"), frames, 10.0)
    import imageio.v2 as imageio

    imageio.imwrite(tmp_path / "optimum_still.png", frames[6])
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1, 2], [3, 1, 2])
    fig.savefig(tmp_path / "cost.png")
    plt.close(fig)
    (tmp_path / "mpc_table.md").write_text("| controller | cost |\n|---|---|\n| D2C-MPC | 1.5 |\n")
    (tmp_path / "config.json").write_text(json.dumps({"experiment": {"seed": 7, "name": "<x&y>"}}))
    metrics = {
        "status": "converged",
        "d2c": {"status": "converged", "cost": 1.5, "iterations": 3},
        "stages": {"d2c": {"status": "done", "wall_s": 2.0}},
        "figures": {
            "cost.png": "written",
            "broken.png": {"status": "failed", "error": "ValueError: no data"},
        },
        "videos": {
            "optimum.mp4": {"status": "written", "trajectories": ["X_star"], "still": "optimum_still.png"},
            "mpc_episodes.mp4": {"status": "skipped", "reason": "no GL context"},
        },
        "mpc_verdict": {"verdict": "held", "text": "every surrogate costs more.", "cause": "MLP 12 %."},
        "wall_time_s": 5.0,
    }
    (tmp_path / "metrics.json").write_text(json.dumps(metrics))
    return tmp_path


def test_the_page_embeds_every_file_and_says_the_verdict(folder):
    text = open(page.write(str(folder))).read()
    assert 'id="status">converged<' in text and "held." in text and "MLP 12 %." in text
    assert "<table>" in text and "<td>D2C-MPC</td>" in text  # the Markdown table, as HTML
    assert "&lt;x&amp;y&gt;" in text and "<x&y>" not in text  # the config, escaped
    videos = re.findall(r'<video [^>]*src="data:video/mp4;base64,([^"]+)"', text)
    assert len(videos) == 1 and base64.b64decode(videos[0]) == (folder / "optimum.mp4").read_bytes()
    assert 'poster="data:image/png;base64,' in text and "no GL context" in text
    images = re.findall(r'<img alt="([^"]+)" src="data:image/png;base64,', text)
    assert images == ["cost.png"]  # the still is the video's poster, not a figure
    assert "broken.png not drawn: ValueError: no data" in text
    assert not re.search(r'(src|href)="(?!data:)[^"]*\.png"', text)  # nothing left outside


def test_the_command_writes_it_once(folder, capsys):
    assert page.main([str(folder)]) == 0
    assert page.main([str(folder)]) == 2 and "exists" in capsys.readouterr().err
    assert page.main([str(folder), "--overwrite"]) == 0
    os.remove(folder / "metrics.json")
    assert page.main([str(folder), "--overwrite"]) == 2


def _browser():
    """playwright's sync API; skips without chromium or playwright, unless CI requires them."""
    required = bool(os.environ.get("MJX_SURROGATE_REQUIRE_BROWSER"))
    if CHROMIUM is None:
        assert not required, "MJX_SURROGATE_REQUIRE_BROWSER is set but chromium is missing"
        pytest.skip("no chromium (CI installs Debian's)")
    if required:
        import playwright.sync_api

        return playwright.sync_api
    return pytest.importorskip("playwright.sync_api")


@pytest.mark.slow  # over 5 s: the fast tier's budget
def test_the_page_renders_in_a_headless_browser(folder, tmp_path_factory):
    sync_playwright = _browser().sync_playwright
    path = page.write(str(folder))
    shot = str(tmp_path_factory.mktemp("shot") / "page.png")
    flags = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update"]
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=CHROMIUM, args=[*flags, "--disable-sync", "--disable-quic"]
        )
        try:
            tab = browser.new_page(viewport={"width": 1000, "height": 800})
            tab.goto("file://" + os.path.abspath(path))
            tab.wait_for_function(
                "[...document.querySelectorAll('video')].every(v => v.readyState >= 2)", timeout=15000
            )
            videos = tab.evaluate(
                "[...document.querySelectorAll('video')].map(v => [v.videoWidth, v.videoHeight])"
            )
            images = tab.evaluate("[...document.querySelectorAll('img')].map(i => i.naturalWidth)")
            status = tab.inner_text("#status")
            tab.screenshot(path=shot, full_page=True)
        finally:
            browser.close()
    assert videos == [[64, 48]] and len(images) == 1 and images[0] > 100 and status == "converged"
    from tests.helpers import assert_png

    assert_png(shot)
