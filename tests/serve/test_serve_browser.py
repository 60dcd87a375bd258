"""The vtts serve page in a real browser: Debian's headless Chromium (one for the module) opens
the page of a real server, which opens its session and loads its head.

- a ``say`` is heard (``audiostart``, then ``end``) with the face drawn on the audio's clock,
  never ahead of it;
- ``stop`` silences it at once and the next text starts cleanly; a bad bookmark is an ``error``;
- the page posed with a parameter vector draws the head vtts render draws for it (the
  Transforms' head and eye rotations included): silhouette IoU ≥ 0.99.

Setup installs chromium (scripts/setup.sh); without it these tests fail, they do not skip.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from vtts.export.browser import Chromium, find_chromium

from ..export.test_web_browser import covered, iou, rgba

SIZE = (352, 288)
SILHOUETTE_IOU = 0.99


@pytest.fixture(scope="module")
def page():
    from vtts.serve.server import Server, load_heads, warm_up

    binary = find_chromium()
    if binary is None:
        pytest.fail("no chromium: scripts/setup.sh installs Debian's chromium for these tests")
    server = Server(load_heads(["cybatt"]))
    warm_up(server)
    with (
        server.running() as url,
        Chromium(
            SIZE, transparent=True, autoplay=True, fake_microphone=True, binary=binary
        ) as browser,  # fmt: skip
    ):
        browser.load(f"{url}/?bar=0&background=transparent")
        yield server, browser


SAY = """(text) => new Promise((resolve) => {
  const t0 = performance.now(); const seen = {};
  const session = vtts.session;
  session.handlers.clear();
  vtts.on('audiostart', (e) => {
    seen.audiostart = e.at - t0;
    const u = session.utterances.get(e.utterance);  // the face's first frame came before it
    seen.face = u !== undefined && u.faces.length > 0 && u.faces[0].start === 0;
  });
  vtts.on('end', (e) => { seen.end = e.at - t0; seen.sync = vtts.sync(); resolve(seen); });
  vtts.on('error', (e) => resolve({ error: e }));
  vtts.say(text);
})"""


def test_a_say_is_heard_with_the_face_on_the_audio_clock(page):
    _, browser = page
    before = browser.evaluate("vtts.framesDrawn")
    seen = browser.evaluate(f"({SAY})({json.dumps('Hello there, how are you today?')})")
    assert "error" not in seen, seen
    assert 0 < seen["audiostart"] < 1000  # ms; the benchmark measures it (bench_serve.py)
    assert seen["face"]
    assert seen["end"] - seen["audiostart"] > 1500  # the whole utterance, about 2 s
    sync = seen["sync"]
    assert sync["frames"] > 5  # drawn frames: a loaded machine draws a few a second
    assert sync["maxAhead"] <= 1e-6  # never a frame ahead of its sound
    assert sync["maxBehind"] <= 1 / 30 + 1e-6  # and never more than a frame behind
    assert browser.evaluate("vtts.framesDrawn") - before > 5
    assert browser.evaluate("vtts.underruns") == 0


def test_stop_silences_at_once_and_the_next_text_starts(page):
    _, browser = page
    result = browser.evaluate(
        """new Promise((resolve) => {
      vtts.session.handlers.clear();
      vtts.on('audiostart', () => setTimeout(() => {
        const level = vtts.level(); const t = performance.now(); vtts.stop();
        const poll = () => {
          if (vtts.level() === 0) resolve({ level, ms: performance.now() - t });
          else setTimeout(poll, 1);
        };
        poll();
      }, 400));
      vtts.say('This is a longer sentence, and it will be stopped in the middle of it.');
    })"""
    )
    assert result["level"] > 0.001  # it was speaking
    assert result["ms"] < 100
    seen = browser.evaluate(f"({SAY})('Again.')")
    assert "audiostart" in seen and "end" in seen


MIC = """() => new Promise(async (resolve) => {
  const session = vtts.session;
  session.handlers.clear();
  const seen = { shown: 0 };
  let number = null;
  const poll = setInterval(() => {
    const f = session.frameAt();
    if (f !== null && f.utterance === number) seen.shown += 1;
  }, 20);
  vtts.on('listening', (m) => { number = m.utterance; seen.listening = m.rate; });
  vtts.on('audiostart', () => { seen.audiostart = true; });
  vtts.on('end', (e) => {
    const u = session.utterances.get(e.utterance);
    seen.frames = u ? u.faces.reduce((n, f) => n + f.frames, 0) : -1;
    seen.faces = u ? u.faces.length : -1;
    clearInterval(poll); seen.duration = e.duration; resolve(seen);
  });
  vtts.on('error', (e) => { clearInterval(poll); resolve({ error: e }); });
  try { seen.rate = await vtts.microphone(); } catch (e) { resolve({ error: String(e) }); return; }
  setTimeout(() => vtts.stopMicrophone(), 1500);
})"""


def test_the_microphone_is_a_voice_the_face_follows(page):
    """The page's Mic (Chromium's fake microphone, its test beeps): a listen at the audio
    context's rate, face frames streamed back and shown on the voice's clock, an end when the
    microphone stops; then a say is heard again."""
    _, browser = page
    seen = browser.evaluate(f"({MIC})()")
    assert "error" not in seen, seen
    assert seen["listening"] == seen["rate"] >= 8000
    assert seen["frames"] > 15 and seen["audiostart"] and seen["shown"] > 5, seen
    assert 1.0 < seen["duration"] < 4.0
    again = browser.evaluate(f"({SAY})('Hi.')")
    assert "audiostart" in again and "end" in again


def test_a_bad_bookmark_is_an_error_event(page):
    _, browser = page
    seen = browser.evaluate(f"({SAY})('Hello <frown> there.')")
    assert seen["error"]["code"] == "bookmark"
    assert "unknown bookmark <frown>" in seen["error"]["message"]


@pytest.mark.parametrize(
    "pose",
    [
        {"visemes": {10: 1.0}},
        {
            "faps": {
                "head_pitch": 20000,
                "head_yaw": -30000,
                "yaw_l_eyeball": 40000,
                "yaw_r_eyeball": 40000,
            },  # fmt: skip
            "visemes": {1: 1.0},
            "expressions": {"joy": 1.0},
        },
    ],
)
def test_the_page_draws_what_vtts_render_draws(page, pose):
    server, browser = page
    from vtts.render import FaceRenderer

    model = server.heads["cybatt"].model
    params = model.params(pose.get("faps"), visemes=pose.get("visemes"),
                          expressions=pose.get("expressions"))  # fmt: skip
    browser.evaluate(
        f"new Promise((r) => {{ vtts.hold({json.dumps(params.tolist())});"
        " requestAnimationFrame(() => requestAnimationFrame(r)); })"
    )
    shot = rgba(browser.screenshot())
    browser.evaluate("vtts.hold(null)")
    with FaceRenderer([model], size=SIZE, background="transparent") as renderer:
        ours = renderer.render([params])
    assert covered(ours).sum() > 0.1 * SIZE[0] * SIZE[1]
    value = iou(covered(ours), covered(shot))
    assert value >= SILHOUETTE_IOU, f"silhouette IoU {value:.4f}"
    # and the pose moved the head: it is not the neutral silhouette
    with FaceRenderer([model], size=SIZE, background="transparent") as renderer:
        neutral = renderer.render([np.zeros_like(params)])
    if "faps" in pose:
        assert iou(covered(neutral), covered(shot)) < 0.99
