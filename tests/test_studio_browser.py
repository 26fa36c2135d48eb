"""The studio in a real headless browser (issue 41, "Tests"): Debian's chromium driven
through chromium-driver by Selenium (mimarble/studio/headless.py; .ci/run installs them).

The page is loaded with its token (and refused without), the period slider is moved with
the arrow keys and the render changes, an invalid value typed shows the parameter
table's sentence beside its control, Save writes the file changing only the period's
text, the file edited on disk reloads (and a parse error shows as FILE:LINE:COL), and
the browser's console holds no error. They skip, saying why, only where no browser can
be started. The scene is a 96×96 copy of fig11a in a temporary folder.
"""

import difflib
import re
import time

import pytest

pytest.importorskip("uvicorn", reason="the studio extra is not installed")

from mimarble.studio.headless import browser_problem  # noqa: E402

problem = browser_problem()
pytestmark = pytest.mark.skipif(problem is not None, reason=f"no headless browser: {problem}")

from mimarble import scene as scene_language  # noqa: E402
from mimarble.runtime import packaged_scenes  # noqa: E402
from mimarble.studio import StudioSession  # noqa: E402
from mimarble.studio.server import StudioServer  # noqa: E402

KEY = "marble.period"


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    text = packaged_scenes.find("fig11a").read_text()
    text = text.replace("width 500 height 500 samples 4", "width 96 height 96 samples 1")
    path = tmp_path_factory.mktemp("studio-browser") / "marble.scene"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def studio(scene_file):
    from mimarble.studio.headless import start_browser
    session = StudioSession(scene_file)
    server = StudioServer(session).start()
    driver = start_browser()
    try:
        yield driver, server, session
    finally:
        driver.quit()
        server.stop()
        session.close()


def wait(driver, script, timeout=60.0, what="the page"):
    """Poll ``script`` (returns a truthy value when done) in the page."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.05)
    said = driver.execute_script("return [document.getElementById('message').textContent, "
                                 "document.getElementById('banner').textContent]")
    raise AssertionError(f"{what}: not within {timeout} s; the page says {said}")


def control(driver, label_text):
    """The control whose <label> reads ``label_text`` (its accessible name)."""
    label = driver.find_element("xpath", f"//label[normalize-space()='{label_text}']")
    return driver.find_element("id", label.get_attribute("for"))


def frames_shown(driver):
    return driver.execute_script("return window.studio.frames.length")


def test_the_page_is_refused_without_its_token_and_shown_with_it(studio):
    driver, server, _ = studio
    driver.get(server.url.split("?")[0])
    assert "needs its token" in driver.find_element("tag name", "body").text
    driver.get_log("browser")                     # the refusal's 403 is logged: not the page's
    driver.get(server.url)
    wait(driver, "return window.studio && window.studio.frames.length > 0", what="a frame")
    assert driver.find_element("id", "frame").get_attribute("src").startswith("blob:")
    slider = control(driver, KEY)
    assert slider.get_attribute("type") == "range"
    # every control has an accessible name holding its parameter's name
    unnamed = driver.execute_script("""
        return [...document.querySelectorAll('#controls input, #controls select')]
          .filter((e) => !(e.labels && e.labels.length) && !e.getAttribute('aria-label'))
          .map((e) => e.outerHTML);""")
    assert unnamed == []


def test_the_period_slider_moves_with_the_arrow_keys_and_the_render_changes(studio):
    from selenium.webdriver.common.keys import Keys
    driver, server, session = studio
    wait(driver, "return window.studio.state && !window.studio.state.rendering",
         what="the first frame refined")
    image = driver.find_element("id", "frame")
    before_png = image.screenshot_as_png
    before = float(control(driver, KEY).get_attribute("value"))
    version = driver.execute_script("return window.studio.version")
    slider = control(driver, KEY)
    driver.execute_script("arguments[0].focus()", slider)     # a click would move it
    for _ in range(5):
        slider.send_keys(Keys.ARROW_RIGHT)
    after = float(slider.get_attribute("value"))
    assert after > before
    wait(driver, f"return window.studio.version > {version} && window.studio.state "
                 "&& !window.studio.state.rendering", what="a frame of the new period")
    time.sleep(0.3)
    assert image.screenshot_as_png != before_png
    values = {k.path: k.value for k in _keys(session.scene) if k.path.endswith(".period")}
    assert values[KEY] == pytest.approx(after)


def _keys(scene):
    from mimarble.scene.keys import scene_keys
    return scene_keys(scene).values()


def test_an_invalid_value_typed_shows_the_tables_sentence_beside_its_control(studio):
    driver, server, session = studio
    typed = driver.find_element("id", control(driver, "marble.scale").get_attribute("id")
                                + "-typed")
    version = session.state()["version"]
    typed.clear()
    typed.send_keys("-2\n")
    error = wait(driver, "const e = document.getElementById('c-marble_scale-error');"
                         "return e && e.textContent", what="the sentence")
    assert "scale" in error and "-2" in error
    assert session.state()["version"] == version           # the render kept the last valid


def test_save_changes_only_the_periods_text(studio, scene_file):
    driver, server, session = studio
    original = session.text
    period = session.edits_made.get(KEY)
    assert period is not None                              # the slider's edit, above
    driver.find_element("id", "save").click()
    wait(driver, "return window.studio.done.some((m) => m.action === 'save')", what="saved")
    saved = scene_file.read_text()
    changed = [line for line in difflib.ndiff(original.splitlines(), saved.splitlines())
               if line[:2] in ("- ", "+ ")]
    assert changed and all("period" in line for line in changed), changed
    reparsed = scene_language.parse(saved)
    assert [k.value for k in _keys(reparsed) if k.path == KEY] == [pytest.approx(period)]


def test_the_file_edited_on_disk_reloads_and_a_parse_error_is_shown(studio, scene_file):
    driver, server, session = studio
    text = scene_file.read_text()
    scene_file.write_text(text.replace("distortion 3.0", "distortion 4.5"))
    wait(driver, "const e = document.getElementById('c-marble_distortion');"
                 "return e && Number(e.value) === 4.5", what="the reloaded distortion")
    broken = re.sub(r"\n(\s+)period ", r"\n\1perod ", text, count=1)
    assert broken != text
    scene_file.write_text(broken)
    banner = wait(driver, "const b = document.getElementById('banner');"
                          "return !b.hidden && b.textContent", what="the parse error")
    assert f"{scene_file}:" in banner and "last good render" in banner
    scene_file.write_text(text)
    wait(driver, "return document.getElementById('banner').hidden", what="the banner gone")


def test_a_stop_colour_picked_edits_that_stop_and_the_histogram_is_drawn(studio):
    driver, server, session = studio
    picker = driver.find_element("css selector", f"[aria-label='{KEY.replace('period', 'ramp')} stop 0 colour']")
    driver.execute_script("arguments[0].value = '#0000ff';"
                          "arguments[0].dispatchEvent(new Event('input', {bubbles: true}))", picker)
    deadline = time.time() + 30
    while session.edits_made.get("marble.ramp.0") != "#0000ff" and time.time() < deadline:
        time.sleep(0.05)
    assert session.edits_made.get("marble.ramp.0") == "#0000ff"
    # the histogram of t under the ramp: bars drawn above the ramp's gradient strip
    painted = wait(driver, """
        const c = document.querySelector("canvas.histogram[data-prefix='marble']");
        if (!c) return 0;
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height - 12).data;
        let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
        return n;""", what="the histogram drawn")
    assert painted > 100


def test_dragging_the_image_orbits_and_the_wheel_zooms(studio):
    from selenium.webdriver.common.action_chains import ActionChains
    driver, server, session = studio
    camera = session.scene.camera
    image = driver.find_element("id", "frame")
    ActionChains(driver).move_to_element(image).click_and_hold().move_by_offset(60, 0) \
        .move_by_offset(60, 10).release().perform()
    deadline = time.time() + 30
    while session.scene.camera == camera and time.time() < deadline:
        time.sleep(0.05)
    orbited = session.scene.camera
    assert orbited != camera
    driver.execute_script("arguments[0].dispatchEvent(new WheelEvent('wheel', "
                          "{deltaY: -200, bubbles: true, cancelable: true}))", image)
    deadline = time.time() + 30
    while session.scene.camera == orbited and time.time() < deadline:
        time.sleep(0.05)
    assert session.scene.camera != orbited


def test_the_browser_console_has_no_errors(studio):
    driver, _, _ = studio
    from mimarble.studio.headless import console_errors
    assert console_errors(driver) == []
