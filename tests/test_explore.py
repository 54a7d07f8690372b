"""The interactive explorer: its answers against the library's own functions, its server, its
command, and the page in a real browser (headless Chromium; skipped where none is installed)."""

import json
import math
import os
import shutil
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from cosserat_channel import solve_point
from cosserat_channel.atlas import classify
from cosserat_channel.cli import main
from cosserat_channel.explorer import server, answers
from cosserat_channel.parameters import ParameterError, N_from_friction, eps_from_width
from cosserat_channel.sweep.spec import load_sweep

MATERIAL = {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0}


def form(**changes):
    f = server.default_form()
    f.update(changes)
    return f


# ---------------------------------------------------------------------------------------------
# answers: the page's questions, answered by the public API
# ---------------------------------------------------------------------------------------------
def test_read_inputs_takes_fractions_and_the_engineers_inputs():
    inp = answers.read_inputs(form(eps="1/30", A="1/3"))
    assert inp["point"] == (1 / 30, 10.0, 0.5, 1 / 3, 1.0)
    assert inp["material"]["d_p"] == 0.002
    inp = answers.read_inputs(form(eps_from="W", W="0.06", N_from="delta_w", delta_w="20"))
    assert inp["point"][0] == eps_from_width(0.002, 0.06)
    assert inp["point"][4] == N_from_friction(25.0, 20.0)
    assert inp["given"] == {"W": 0.06, "d_p": 0.002, "delta_w": 20.0, "phi": 25.0}
    assert answers.read_inputs(form(material=False))["material"] is None


@pytest.mark.parametrize("changes, words", [
    ({"L": "abc"}, ["L:", "number", "'abc'"]),
    ({"eps": "2"}, ["eps", "(0, 1]"]),
    ({"N": ""}, ["N:", "give a number"]),
    ({"eps_from": "W", "W": "-1"}, ["W", "outside"]),
    ({"rtol": "1"}, ["rtol", "1e-13"]),
    ({"d_p": "1e9"}, ["d_p", "outside"]),
])
def test_bad_input_is_one_line_naming_it(changes, words):
    with pytest.raises(ParameterError) as exc:
        answers.read_inputs(form(**changes))
    message = str(exc.value)
    assert "\n" not in message
    for w in words:
        assert w in message


def test_point_is_solve_points_answer():
    a = answers.point(form(eps="0.05", K="2", A="0.5", N="1.2"))
    r = solve_point(0.05, 10.0, 2.0, 0.5, 1.2, material=MATERIAL,
                    profile=np.linspace(0, 1, answers.PROFILE_POINTS), sensitivities=True)
    assert a["status"] == r.status.name == "ok"
    assert a["message"] == r.status.message
    for name, value in r.values.items():
        assert a["outputs"][name] == (value if math.isfinite(value) else None)
    assert a["sensitivities"]["Delta"]["eps"] == r.sensitivities["Delta"]["eps"]
    assert a["profile"]["u_over_u0"] == r.profile["u_over_u0"].tolist()
    json.dumps(a, allow_nan=False)  # what the server sends


def test_point_without_solution_says_why():
    a = answers.point(form(eps="0.5", L="100"))
    r = solve_point(0.5, 100.0, 0.5, 1 / 3, 1.0)
    assert r.status.name != "ok"
    assert (a["status"], a["message"]) == (r.status.name, r.status.message)
    assert a["profile"] is None and a["outputs"]["Delta"] is None
    json.dumps(a, allow_nan=False)


def test_map_is_the_atlas_classification_at_this_eps_L():
    m = answers.solvability_map(form(eps="0.02", L="20"))
    A, N = np.array(m["A"]), np.array(m["N"])
    codes = np.array(m["codes"])
    assert codes.shape == (N.size, A.size)
    assert np.array_equal(codes, classify(0.02, 20.0, 0.0, A[None, :], N[:, None]))
    # more than one status on the plane, so the picture says something
    assert len(np.unique(codes)) >= 2
    # the same eps L from another (eps, L): the same map, from memory
    assert answers.solvability_map(form(eps="0.04", L="10"))["codes"] == m["codes"]


def test_line_is_solves_answer_with_the_point_on_it():
    a = answers.line(form(line_x="A", line_y="Delta", A="0.7"))
    x = np.array(a["x"])
    assert 0.7 in a["x"] and a["at"] == 0.7
    assert x.min() == answers.SLIDERS["A"]["lo"] and x.max() == answers.SLIDERS["A"]["hi"]
    k = a["x"].index(0.7)
    assert a["y"][k] == solve_point(1 / 30, 10.0, 0.5, 0.7, 1.0).Delta
    r = solve_point(1 / 30, 10.0, 0.5, x[0], 1.0)
    assert a["status"][0] == int(r.status)


def test_line_refuses_a_material_output_without_material():
    with pytest.raises(ParameterError, match="nu needs the material"):
        answers.line(form(material=False, line_y="nu"))


def test_export_writes_a_sweep_file_that_reproduces_the_line_and_replaces_nothing(tmp_path):
    (tmp_path / "explore-1.toml").write_text("mine")
    f = form(line_x="K", line_y="slip", eps_from="W", W="0.05")
    written = answers.export(f, str(tmp_path))["written"]
    assert [os.path.basename(p) for p in written] == ["explore-2.toml", "explore-2.png",
                                                       "explore-2-profiles.png"]
    assert (tmp_path / "explore-1.toml").read_text() == "mine"
    for p in written[1:]:
        assert open(p, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    spec = load_sweep(written[0])
    line = answers.line(f)
    assert spec.K.tolist() == line["x"]
    assert spec.eps.tolist() == [eps_from_width(0.002, 0.05)]
    assert spec.variables == ("slip",)
    assert spec.material["phi"] == 25.0


# ---------------------------------------------------------------------------------------------
# server: JSON over HTTP on 127.0.0.1, slow work to the background
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def running(tmp_path):
    app = server.Running(directory=str(tmp_path))
    yield app
    # The warm-up (kernels loaded, a map and a line computed: seconds) runs on after stop(), in
    # this process: it ends here, not during the next tests (whose peak-memory measurements
    # would count its arrays).
    app.explorer.warm.wait(600)
    app.stop()


def _post(url, kind, f, seq=1):
    req = urllib.request.Request(url + "api/" + kind, data=json.dumps({"seq": seq, "form": f})
                                 .encode(), headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=600) as resp:
        return json.loads(resp.read())


def _finish(url, answer):
    while "pending" in answer:
        with urllib.request.urlopen(url + "api/job/" + answer["pending"], timeout=600) as resp:
            answer = json.loads(resp.read())
    return answer


def test_server_answers_the_page_and_refuses_other_hosts(running):
    url = running.url
    assert url.startswith("http://127.0.0.1:")
    with urllib.request.urlopen(url, timeout=60) as resp:
        assert b"cosserat-channel explorer" in resp.read()
    with urllib.request.urlopen(url + "static/app.js", timeout=60) as resp:
        assert b"plotLines" in resp.read()
    a = _finish(url, _post(url, "point", form(eps="0.05")))
    assert a["status"] == solve_point(0.05, 10, 0.5, 1 / 3, 1).status.name
    assert a["outputs"]["Delta"] == solve_point(0.05, 10, 0.5, 1 / 3, 1).Delta
    bad = _finish(url, _post(url, "point", form(eps="nonsense"), seq=2))
    assert set(bad) >= {"error"} and "eps" in bad["error"]
    req = urllib.request.Request(url + "api/meta", headers={"Host": "evil.example:80"})
    with pytest.raises(urllib.error.HTTPError) as exc:
        urllib.request.urlopen(req, timeout=60)
    assert exc.value.code == 403


def test_slow_work_goes_to_the_background_and_stale_work_is_dropped(tmp_path):
    app = server.Explorer(str(tmp_path), budget=0.0)
    gate = threading.Event()
    try:
        app.warm.set()
        # the slow pool's one thread waits on the gate, so that no answer can come within the
        # budget, however fast the machine: every request below goes to the background
        app.pools[server.KINDS["line"][0]].submit(gate.wait, 600)
        first = app.ask("line", 1, form(line_x="L"))
        assert "pending" in first and "background" in first["note"]
        second = app.ask("line", 2, form(line_x="N"))
        # another page counts its own requests: its first is not overtaken by this page's second
        other = app.ask("line", 1, form(line_x="K"), client="another page")
        assert "pending" in second and "pending" in other
        gate.set()
        assert app.job(second["pending"], wait=600)["x_name"] == "N"
        # the first was overtaken by the second before it could start: dropped unrun
        assert app.job(first["pending"], wait=600) == {"stale": True}
        assert app.job(other["pending"], wait=600)["x_name"] == "K"
    finally:
        gate.set()
        app.close()


def test_command_refuses_a_bad_port_in_one_line(capsys):
    assert main(["explore", "--port", "70000", "--no-browser"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--port" in err


def test_notebook_function_shows_the_page(running):
    import cosserat_channel

    html = running._repr_html_()
    assert running.url in html and "<iframe" in html
    assert callable(cosserat_channel.explore)


# ---------------------------------------------------------------------------------------------
# the page in a real browser
# ---------------------------------------------------------------------------------------------
def _browser():
    """A headless Chromium driven through chromedriver, or a skip naming what to install."""
    from cosserat_channel.explorer import chromium

    reason = chromium.missing()
    if reason:
        pytest.skip(f"the browser test needs what is missing: {reason}")
    driver, profile = chromium.driver()
    driver.set_script_timeout(60)
    return driver, profile


def _wait(driver, script, timeout=900.0):
    """Poll ``script`` (JavaScript returning a value) until it is truthy; returns it."""
    t0 = time.monotonic()
    while True:
        value = driver.execute_script(script)
        if value:
            return value
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"the page did not show {script!r} within {timeout:g} s")
        time.sleep(0.05)


def _shown(driver):
    """The point the page shows, the status badge and Delta as the page has them."""
    return driver.execute_script(
        "const d = document.getElementById('out-Delta');"
        "return [window.explore.point && window.explore.point.point,"
        " document.getElementById('status').textContent,"
        " document.getElementById('status-message').textContent,"
        " d ? d.dataset.value : null, document.getElementById('error').textContent];")


def _settled(driver, **at):
    """Wait until the page shows the point with ``at``'s values and nothing is pending."""
    cond = " && ".join(f"Math.abs(p.{k} - {v!r}) <= 1e-12 * Math.abs({v!r})" for k, v in at.items())
    _wait(driver, "const p = window.explore.point && window.explore.point.point;"
                  f"return p && {cond} && window.explore.idle();")
    return _shown(driver)


def _type(driver, name, text):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    box = driver.find_element(By.ID, "in-" + name)
    box.send_keys(Keys.CONTROL, "a")  # select what is there and type over it, as a person does
    box.send_keys(text + Keys.ENTER)


def _check_against_solve_point(shown):
    p, status, message, delta, error = shown
    r = solve_point(p["eps"], p["L"], p["K"], p["A"], p["N"], material=MATERIAL)
    assert status == r.status.name
    assert message.startswith(r.status.message)
    assert error == ""
    if r.ok:
        # the same function on the same inputs: the page shows solve_point's double exactly
        assert float(delta) == r.Delta
    else:
        assert delta == ""
    return r


@pytest.mark.slow
def test_page_in_a_browser_answers_like_solve_point(tmp_path):
    driver, profile = _browser()
    app = server.Running(directory=str(tmp_path))
    try:
        from selenium.webdriver.common.by import By
        from selenium.webdriver.common.keys import Keys

        driver.get(app.url)
        _wait(driver, "return window.explore.ready")
        # the paper's figure 2 at start
        r = _check_against_solve_point(_settled(driver, eps=1 / 30, L=10.0, A=1 / 3))
        assert r.ok and abs(r.Delta - 10.253) < 1e-3  # docs/model.md: 10.253

        # a typed value (a fraction)
        _type(driver, "eps", "1/20")
        _check_against_solve_point(_settled(driver, eps=1 / 20))

        # the A slider moved by the keyboard, as a person would
        slider = driver.find_element(By.ID, "sl-A")
        slider.click()
        before = driver.execute_script("return window.explore.point.point.A")
        for _ in range(15):
            slider.send_keys(Keys.ARROW_RIGHT)
        A = float(driver.find_element(By.ID, "in-A").get_attribute("value"))
        assert A != before
        _check_against_solve_point(_settled(driver, A=A))

        # a point without solution: its status and sentence
        _type(driver, "A", "1/3")
        _type(driver, "L", "100")
        _type(driver, "eps", "0.5")
        r = _check_against_solve_point(_settled(driver, eps=0.5, L=100.0, A=1 / 3))
        assert not r.ok

        # a bad input: one line on the page, nothing else changes
        _type(driver, "L", "abc")
        error = _wait(driver, "return document.getElementById('error').textContent")
        assert "L:" in error and "'abc'" in error and "\n" not in error
        _type(driver, "L", "10")
        _type(driver, "eps", "0.03")
        _check_against_solve_point(_settled(driver, eps=0.03, L=10.0))

        # a click on the map moves the point there
        canvas = driver.find_element(By.ID, "map")
        from selenium.webdriver.common.action_chains import ActionChains

        ActionChains(driver).move_to_element_with_offset(canvas, 40, -60).click().perform()
        A = float(driver.find_element(By.ID, "in-A").get_attribute("value"))
        N = float(driver.find_element(By.ID, "in-N").get_attribute("value"))
        _check_against_solve_point(_settled(driver, A=A, N=N))
        assert driver.execute_script("return window.explore.map.codes.length") == answers.MAP_N

        # back to figure 2, and a picture a person can look at
        for name, text in (("A", "1/3"), ("N", "1"), ("eps", "1/30")):
            _type(driver, name, text)
        _check_against_solve_point(_settled(driver, eps=1 / 30, A=1 / 3, N=1.0))
        _wait(driver, "return window.explore.last.line && window.explore.idle()")
        shot = os.environ.get("EXPLORE_SCREENSHOT") or str(tmp_path / "explore.png")
        assert driver.save_screenshot(shot)
        assert os.path.getsize(shot) > 10_000
        print(f"screenshot: {shot}")
    finally:
        driver.quit()
        app.stop()
        shutil.rmtree(profile, ignore_errors=True)
