"""The web viewer of `chronomap serve`, driven in a real browser (Chromium through WebDriver).

A service is started with real data: the greg office door (FreMEn and a histogram), the
Witham Wharf robot's speed through a lab door (a continuous state), the Aruba apartment's 10
areas and the synthetic office as occupancy grids, the Witham Wharf topological map and a
CoPA-Map of the ATC shopping centre. For every view the test waits until the page has drawn,
reads back what it plotted (each chart keeps its numbers in data-* attributes) and compares
them with the API's own answers, takes a screenshot, and fails on any JavaScript error in the
browser console.

Run (from the repository root, after `cargo build`):

    python3 -m venv target/browser-venv && target/browser-venv/bin/pip install selenium pytest
    target/browser-venv/bin/python -m pytest -q tests/browser

Environment: CHRONOMAP_BIN (default target/debug/chronomap), CHROMIUM (default
/usr/bin/chromium), CHROMEDRIVER (default /usr/bin/chromedriver), CHRONOMAP_SCREENSHOTS (where
screenshots go; default target/browser-screenshots). Without Chromium the tests skip, unless
CHRONOMAP_REQUIRE_BROWSER=1 (as in CI).
"""

import json
import lzma
import os
import re
import shutil
import struct
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "data"
BIN = Path(os.environ.get("CHRONOMAP_BIN", ROOT / "target" / "debug" / "chronomap"))
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver")
SHOTS = Path(os.environ.get("CHRONOMAP_SCREENSHOTS", ROOT / "target" / "browser-screenshots"))
REQUIRED = os.environ.get("CHRONOMAP_REQUIRE_BROWSER") == "1"

# 2016-03-07 00:00 UTC, a Monday: the last full week of the greg door's training data.
GREG_WEEK = 1457308800


def missing(what):
    if REQUIRED:
        pytest.fail(f"{what} (CHRONOMAP_REQUIRE_BROWSER=1)")
    pytest.skip(what)


def run(*args):
    done = subprocess.run([str(BIN), *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, f"chronomap {' '.join(map(str, args))}: {done.stderr}"
    return done.stdout


def series(path):
    """`t value` lines of a bundled (.xz) file."""
    times, values = [], []
    with lzma.open(path, "rt") as f:
        for line in f:
            t, v = line.split()[:2]
            times.append(float(t))
            values.append(float(v))
    return times, values


class Service:
    def __init__(self, url, token):
        self.url, self.token = url, token

    def call(self, method, path, body=None, auth=False):
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(self.url + path, data=data, method=method)
        request.add_header("content-type", "application/json")
        if auth:
            request.add_header("authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(request, timeout=120) as r:
                return json.load(r)
        except urllib.error.HTTPError as e:
            raise AssertionError(f"{method} {path}: {e.code} {e.read().decode()}") from None

    def get(self, path):
        return self.call("GET", path)

    def post(self, path, body):
        return self.call("POST", path, body)


@pytest.fixture(scope="module")
def service():
    if not BIN.exists():
        missing(f"{BIN} is not built (cargo build)")
    work = Path(tempfile.mkdtemp(prefix="chronomap-viewer-"))
    witham = work / "witham.cmt"
    run("topo", "fit", "--edges", DATA / "witham_topological_nav" / "edges", "-o", witham, "-q")
    aruba = work / "aruba.cmg"
    rooms = sorted((DATA / "aruba_rooms_1min").glob("presence_minutes_*.txt.xz"),
                   key=lambda p: int(re.search(r"_(\d+)\.txt", p.name).group(1)))
    run("grid", "build", "--cell-series", ",".join(map(str, rooms)), "-o", aruba, "-q")
    # The same map with node positions from a Nav2 route-server GeoJSON file (made up here: the
    # Witham data carry none), in a 6-column grid 3 m apart.
    nodes = sorted({part for f in (DATA / "witham_topological_nav" / "edges").glob("*.data.xz")
                    for part in f.name.removesuffix(".data.xz").split("_", 1)})
    assert len(nodes) == 18
    layout = work / "witham_layout.geojson"
    layout.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"id": i, "metadata": {"name": name}},
         "geometry": {"type": "Point", "coordinates": [3.0 * (i % 6), -3.0 * (i // 6)]}}
        for i, name in enumerate(nodes)]}))
    office = work / "office.cmg"
    run("grid", "build", "--synthetic", "--cells", "20000", "--days", "14", "-o", office, "-q")
    office3d = work / "office3d.cmg"
    run("grid", "build", "--synthetic", "--days", "2", "-o", office3d, "-q")
    atc = work / "atc.cmcopa"
    run("activity", "fit", "--train", DATA / "atc_copa_map_grid" / "grid_atc_50cm_60min_train_xy.csv.xz",
        "--inducing", "60", "--iterations", "40", "-o", atc, "-q")
    process = subprocess.Popen(
        [str(BIN), "serve", "--data", str(work / "store"), "--listen", "127.0.0.1:0",
         "--topo", f"witham={witham},witham_laid_out={witham}",
         "--topo-layout", f"witham_laid_out={layout}", "--grid", f"aruba={aruba},office={office},office3d={office3d}",
         "--activity", f"atc={atc}",
         "--activity-map", f"atc={DATA / 'atc_copa_map_grid' / 'atc_map.yaml'}"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        match = re.search(r"listening on (http://\S+)", line)
        assert match, f"the service did not start: {line}{process.stderr.read()}"
        token = (work / "store" / "token").read_text().strip()
        svc = Service(match.group(1), token)
        # Models are written through the API, as a robot would.
        times, values = series(DATA / "door_greg_2016" / "training_data.txt.xz")
        for id, model in [("greg_door", "fremen:2"), ("greg_door_hist", "hist:24")]:
            svc.call("PUT", f"/v1/models/{id}", {"model": model}, auth=True)
            svc.call("POST", "/v1/addvalues", {"id": id, "times": times, "values": values}, auth=True)
        times, values = series(DATA / "witham_topological_nav" / "labdoor_velocity" / "training_data.txt.xz")
        svc.call("PUT", "/v1/models/labdoor_speed", {"model": "fremen:2", "range": [0.0, 0.8]}, auth=True)
        svc.call("POST", "/v1/addvalues", {"id": "labdoor_speed", "times": times, "values": values}, auth=True)
        yield svc
    finally:
        process.terminate()
        process.wait(timeout=30)
        shutil.rmtree(work, ignore_errors=True)


@pytest.fixture(scope="module")
def browser():
    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        missing(f"no Chromium/ChromeDriver at {CHROMIUM} / {CHROMEDRIVER}")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service as DriverService
    except ImportError:
        missing("selenium is not installed")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    # Headless, and no connection anywhere but the service on loopback.
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--disable-dev-shm-usage", "--window-size=1500,1000",
                 "--force-device-scale-factor=1", "--lang=en-GB"]:
        options.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="chronomap-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=DriverService(executable_path=CHROMEDRIVER))
    driver.set_script_timeout(120)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture
def page(browser, service):
    """The browser, with the console checked after the test: no JavaScript error, and no failed
    request but those the test expects (`page.expected_failures`)."""
    browser.get_log("browser")  # drop what earlier tests left

    class Page:
        driver = browser
        url = service.url
        expected_failures = 0

        def open(self, tab):
            browser.get("about:blank")  # a fresh page, not a hash change in the old one
            browser.get(f"{service.url}/#{tab}")

        def ready(self, element_id, timeout=120):
            """Waits for a chart to be drawn (or to fail, which fails the test)."""
            deadline = time.time() + timeout
            while time.time() < deadline:
                state = browser.execute_script(
                    "const e = document.getElementById(arguments[0]); return e && e.dataset.state", element_id)
                if state == "ready":
                    return
                if state == "error":
                    errors = browser.execute_script(
                        "return [...document.querySelectorAll('.error')].map(e => e.textContent).join(' | ')")
                    raise AssertionError(f"#{element_id} shows an error: {errors}")
                time.sleep(0.1)
            raise AssertionError(f"#{element_id} was not drawn in {timeout} s")

        def data(self, element_id, key):
            return json.loads(browser.execute_script(
                "return document.getElementById(arguments[0]).dataset[arguments[1]]", element_id, key))

        def data_or_none(self, element_id, key):
            text = browser.execute_script(
                "return document.getElementById(arguments[0]).dataset[arguments[1]]", element_id, key)
            return None if text is None else json.loads(text)

        def text(self, element_id):
            return browser.execute_script("return document.getElementById(arguments[0]).textContent", element_id)

        def set_value(self, element_id, value, event="change"):
            browser.execute_script(
                "const e = document.getElementById(arguments[0]); e.value = arguments[1];"
                "e.dispatchEvent(new Event(arguments[2]));", element_id, value, event)

        def restart(self, element_id):
            browser.execute_script("document.getElementById(arguments[0]).dataset.state = 'stale'", element_id)

        def shot(self, name):
            """A PNG of the whole page (not only the window), as Chromium's DevTools take it."""
            import base64

            SHOTS.mkdir(parents=True, exist_ok=True)
            width, height = browser.execute_script(
                "return [document.documentElement.scrollWidth, document.documentElement.scrollHeight]")
            png = browser.execute_cdp_cmd("Page.captureScreenshot", {
                "format": "png", "captureBeyondViewport": True,
                "clip": {"x": 0, "y": 0, "width": width, "height": height, "scale": 1}})
            (SHOTS / name).write_bytes(base64.b64decode(png["data"]))

    p = Page()
    yield p
    logs = browser.get_log("browser")
    failures = [e for e in logs if e["level"] == "SEVERE" and e.get("source") == "network"]
    errors = [e for e in logs if e["level"] == "SEVERE" and e.get("source") != "network"]
    assert not errors, f"JavaScript errors in the console: {errors}"
    if p.expected_failures is not None:
        assert len(failures) == p.expected_failures, f"failed requests: {failures}"


def test_models_plot_what_the_api_predicts(page, service):
    page.open("models")
    page.ready("model-chart")
    rows = page.driver.execute_script(
        "return [...document.querySelectorAll('#model-list tbody tr')].map(r => r.dataset.id)")
    assert rows == ["greg_door", "greg_door_hist", "labdoor_speed"]
    # The first model, over the last week of its observations.
    assert page.data("model-chart", "model") == "greg_door"
    times = page.data("model-chart", "times")
    assert times[0] == GREG_WEEK and len(times) == 7 * 96 + 1
    assert page.data("model-chart", "p") == service.post("/v1/predict", {"id": "greg_door", "times": times})["values"]
    assert page.data("model-chart", "entropy") == service.post("/v1/entropy", {"id": "greg_door", "times": times})["values"]
    # A binary model has no prediction interval: its band is p ± half the entropy.
    assert page.data("model-chart", "lower") is None and page.data("model-chart", "upper") is None
    obs = service.get("/v1/models/greg_door/observations")
    week = [(t, v) for t, v in zip(obs["times"], obs["values"]) if GREG_WEEK <= t < GREG_WEEK + 7 * 86400]
    assert page.data("model-chart", "observations") == len(week) == 10080
    anomalies = service.post("/v1/detect", {"id": "greg_door", "times": [t for t, _ in week],
                                            "values": [v for _, v in week], "confidence": 0.8})["anomalies"]
    assert page.data("model-chart", "anomalies") == [a["time"] for a in anomalies]
    assert len(anomalies) > 0
    # The spectrum: the components the model predicts with, strongest first.
    view = service.get("/v1/models/greg_door")
    assert page.data("spectrum-chart", "periods") == [c["period_secs"] for c in view["components"]]
    assert page.data("spectrum-chart", "amplitudes") == [c["amplitude"] for c in view["components"]]
    assert len(view["components"]) == 2
    assert "greg_door — fremen:2" in page.text("model-title")
    page.shot("viewer-models.png")

    # Search, then a continuous model: its values come back in its range.
    page.set_value("model-search", "speed", "input")
    rows = page.driver.execute_script(
        "return [...document.querySelectorAll('#model-list tbody tr')].map(r => r.dataset.id)")
    assert rows == ["labdoor_speed"]
    page.restart("model-chart")
    page.driver.find_element("css selector", "#model-list tbody tr").click()
    page.ready("model-chart")
    times = page.data("model-chart", "times")
    p = page.data("model-chart", "p")
    answer = service.post("/v1/predict", {"id": "labdoor_speed", "times": times, "coverage": 0.9})
    assert p == answer["values"]
    assert all(0.0 <= v <= 1.0 for v in p)
    # Its band is the 90 % prediction interval, in its range.
    lower, upper = page.data("model-chart", "lower"), page.data("model-chart", "upper")
    assert lower == answer["lower"] and upper == answer["upper"]
    assert len(lower) == len(times) and all(0.0 <= a <= b <= 0.8 for a, b in zip(lower, upper))
    assert "90 % prediction interval" in page.text("model-band-legend")
    page.shot("viewer-model-interval.png")
    # A bad threshold is said, not drawn.
    page.set_value("model-confidence", "5")
    assert "(0, 1]" in page.text("model-error")


def test_grids_show_the_predicted_map_its_difference_and_a_cell(page, service):
    page.open("grids")
    page.ready("grid-map")
    assert page.data("grid-map", "grid") == "aruba"
    page.set_value("grid-select", "office")
    page.ready("grid-map")
    time.sleep(0.3)
    page.ready("grid-map")
    assert page.data("grid-map", "grid") == "office"
    info = service.get("/v1/grid/office")
    t = page.data("grid-map", "time")
    answer = service.post("/v1/grid/office/predict", {"time": t})
    assert page.data("grid-map", "shape") == answer["shape"] == info["shape"]
    assert page.data("grid-map", "values") == answer["values"]
    assert page.data("grid-map", "resolution") == answer["resolution"]
    assert page.data("grid-map", "origin") == answer["origin"]
    # The slider moves the time by 1/96 of the span.
    page.restart("grid-map")
    page.set_value("grid-time", "40", "input")
    page.ready("grid-map")
    t40 = page.data("grid-map", "time")
    assert t40 - t == (40 - 56) * 900
    assert page.data("grid-map", "values") == service.post("/v1/grid/office/predict", {"time": t40})["values"]

    # Click a cell at its centre (a real pointer event at viewport coordinates): its p(t) over
    # the day comes from the cell endpoint.
    from selenium.webdriver.common.action_chains import ActionBuilder

    # The cell: the one whose p changes most over the day (a door of the office).
    w, h = info["shape"][0], info["shape"][1]
    day = [service.post("/v1/grid/office/predict", {"time": t40 - 40 * 900 + k * 3 * 3600})["values"]
           for k in range(8)]
    swing = [max(v[i] for v in day) - min(v[i] for v in day) for i in range(w * h)]
    best = max(range(w * h), key=lambda i: swing[i])
    cx, cy = best % w, best // w
    assert swing[best] > 0.5
    rect = page.driver.execute_script(
        "const r = document.querySelector('#grid-map image').getBoundingClientRect();"
        "return [r.left, r.top, r.width, r.height]")
    x = rect[0] + (cx + 0.5) / w * rect[2]
    y = rect[1] + (h - 1 - cy + 0.5) / h * rect[3]
    actions = ActionBuilder(page.driver)
    actions.pointer_action.move_to_location(int(round(x)), int(round(y))).click()
    actions.perform()
    page.ready("grid-cell-chart")
    assert page.data("grid-cell-chart", "cell")[:2] == [cx, cy]
    times = page.data("grid-cell-chart", "times")
    cell = service.post("/v1/grid/office/cell", {"cell": [cx, cy], "times": times})
    assert page.data("grid-cell-chart", "values") == cell["values"]
    # ... the same single-precision numbers as the whole map predicts for that cell (the map
    # travels as shortest f32 decimals, the cell widened to f64).
    f32 = lambda x: struct.unpack("f", struct.pack("f", x))[0]  # noqa: E731
    for k in (0, 10, 50, 96):
        at = service.post("/v1/grid/office/predict", {"time": times[k]})
        assert cell["values"][k] == f32(at["values"][cx + w * cy])

    # The difference to another time: p(t) - p(t'), cell by cell.
    page.restart("grid-map")
    page.driver.find_element("id", "grid-diff").click()
    page.ready("grid-map")
    t_other = page.data("grid-map", "otherTime")
    a = service.post("/v1/grid/office/predict", {"time": t40})["values"]
    b = service.post("/v1/grid/office/predict", {"time": t_other})["values"]
    assert page.data("grid-map", "values") == [x - y for x, y in zip(a, b)]
    assert any(abs(x - y) > 0.5 for x, y in zip(a, b))
    page.shot("viewer-grid-difference.png")
    page.driver.find_element("id", "grid-diff").click()
    page.restart("grid-map")
    page.set_value("grid-time", "60", "input")
    page.ready("grid-map")
    page.shot("viewer-grid.png")

    # A 3-D grid: one layer at a time.
    page.restart("grid-map")
    page.set_value("grid-select", "office3d")
    deadline = time.time() + 60
    while page.data_or_none("grid-map", "grid") != "office3d" or page.data_or_none("grid-map", "layer") != 0:
        assert time.time() < deadline, "the 3-D grid was not drawn"
        time.sleep(0.1)
    page.ready("grid-map")
    w, h, depth = service.get("/v1/grid/office3d")["shape"]
    assert depth > 1 and page.driver.execute_script("return !document.getElementById('grid-layer-box').hidden")
    page.restart("grid-map")
    page.set_value("grid-layer", str(depth // 2))
    page.ready("grid-map")
    assert page.data("grid-map", "layer") == depth // 2
    answer = service.post("/v1/grid/office3d/predict", {"time": page.data("grid-map", "time")})["values"]
    z = depth // 2
    assert page.data("grid-map", "values") == answer[z * w * h:(z + 1) * w * h]


def test_topological_map_colours_edges_and_plans_now_or_later(page, service):
    page.open("topo")
    page.ready("topo-map")
    info = service.get("/v1/topo/witham")
    assert info["positions"] == "computed"
    assert "computed layout" in page.text("topo-positions")
    t = page.data("topo-map", "time")
    predicted = service.post("/v1/topo/witham/predict", {"time": t})["edges"]
    success = page.data("topo-map", "success")
    assert success == {e["id"]: e["success"] for e in predicted}
    assert len(success) == 61
    # Every edge is drawn, with its probability on the element.
    drawn = page.driver.execute_script(
        "return Object.fromEntries([...document.querySelectorAll('#topo-map line[data-edge]')]"
        ".map(l => [l.dataset.edge, +l.dataset.success]))")
    assert drawn == success
    # Each edge carries its 90 % duration interval, and its tooltip says it.
    intervals = page.driver.execute_script(
        "return Object.fromEntries([...document.querySelectorAll('#topo-map line[data-edge]')]"
        ".map(l => [l.dataset.edge, l.dataset.durationInterval.split(',').map(Number)]))")
    assert intervals == {e["id"]: e["duration_interval_secs"] for e in predicted}
    title = page.driver.execute_script(
        "return document.querySelector('#topo-map line[data-edge]').textContent")
    assert "(90 %: " in title, title

    page.driver.find_element("id", "plan-run").click()
    page.ready("plan-chart")
    times = page.data("plan-chart", "times")
    plans = service.post("/v1/topo/witham/plan", {"from": "Station", "task": "F Kitchen", "times": times})["plans"]
    assert page.data("plan-chart", "pmax") == [p["pmax"] for p in plans]
    assert page.data("plan-chart", "expected") == [p["expected_secs"] for p in plans]
    assert page.data("plan-chart", "first") == [p["first_edge"] for p in plans]
    assert "Kitchen" in page.text("plan-summary")
    page.shot("viewer-topo.png")

    # Positions from a layout file: drawn where the file puts them (x to the right, y up), with
    # a metre scale bar.
    page.set_value("topo-select", "witham_laid_out")
    deadline = time.time() + 30
    while "witham_layout.geojson" not in page.text("topo-positions"):
        assert time.time() < deadline, page.text("topo-positions")
        time.sleep(0.1)
    page.ready("topo-map")
    info = service.get("/v1/topo/witham_laid_out")
    assert info["positions"] == "file"
    drawn = page.driver.execute_script(
        "return [...document.querySelectorAll('#topo-map circle')].map(c => [+c.getAttribute('cx'), +c.getAttribute('cy')])")
    assert len(drawn) == len(info["nodes"]) == 18
    (x0, y0), (x1, y1) = drawn[0], drawn[1]
    scale = (x1 - x0) / (info["nodes"][1]["x"] - info["nodes"][0]["x"])
    for (x, y), node in zip(drawn, info["nodes"]):
        assert abs(x - x0 - scale * (node["x"] - info["nodes"][0]["x"])) < 1e-6
        assert abs(y - y0 + scale * (node["y"] - info["nodes"][0]["y"])) < 1e-6
    assert page.driver.execute_script(
        "return [...document.querySelectorAll('#topo-map text')].some(t => / m$/.test(t.textContent))")
    page.restart("topo-map")
    page.set_value("topo-select", "witham")
    page.ready("topo-map")

    # A misspelt node: the service's reason is shown, and the failed request is the only one.
    page.set_value("plan-task", "F Kitchn", "input")
    page.driver.find_element("id", "plan-run").click()
    deadline = time.time() + 30
    while "Kitchn" not in page.text("plan-error") and time.time() < deadline:
        time.sleep(0.1)
    assert "Kitchn" in page.text("plan-error") and "Kitchen" in page.text("plan-error")
    page.expected_failures = 1


def test_plan_panel_plans_for_a_deadline(page, service):
    """"Arrive by T": with a deadline the plan chart draws, for every start time of the day, the
    deadline plan's probability of arriving in time beside the expected-time plan's, as the API
    answers the same request; an invalid deadline is refused in the page (nothing is sent), one
    beyond the service's range shows the service's reason, and an empty one plans as before."""
    page.open("topo")
    page.ready("topo-map")
    plan_requests = lambda: page.driver.execute_script(
        "return performance.getEntriesByType('resource').filter(e => /\\/plan$/.test(e.name)).length")

    def plan(deadline):
        page.set_value("plan-deadline", deadline, "input")
        page.restart("plan-chart")
        page.driver.find_element("id", "plan-run").click()
        page.ready("plan-chart")
        request = {"from": page.driver.execute_script("return document.getElementById('plan-from').value"),
                   "task": page.driver.execute_script("return document.getElementById('plan-task').value"),
                   "times": page.data("plan-chart", "times")}
        assert len(request["times"]) == 96
        return request

    # The kitchen to the station within 100 s (docs/service.md's example): the service's
    # default buckets (1 s).
    page.set_value("plan-from", "Kitchen")
    page.set_value("plan-task", "F Station", "input")
    request = plan("100")
    assert request["from"] == "Kitchen" and request["task"] == "F Station"
    assert page.data("plan-chart", "deadline") == 100
    assert page.data("plan-chart", "bucket") is None
    plans = service.post("/v1/topo/witham/plan", {**request, "deadline_secs": 100})["plans"]
    assert page.data("plan-chart", "inTime") == [p["deadline"]["probability"] for p in plans]
    assert page.data("plan-chart", "minTime") == [p["deadline"]["min_time_probability"] for p in plans]
    assert page.data("plan-chart", "deadlineFirst") == [p["deadline"]["first_edge"] for p in plans]
    assert page.data("plan-chart", "pmax") == [p["pmax"] for p in plans]
    assert page.data("plan-chart", "first") == [p["first_edge"] for p in plans]
    # The deadline plan is never worse than the expected-time plan, nor better than Pmax.
    assert all(p["deadline"]["min_time_probability"] <= p["deadline"]["probability"] <= p["pmax"] + 1e-12
               for p in plans)
    assert any(p["deadline"]["probability"] > p["deadline"]["min_time_probability"] + 0.01 for p in plans)
    # The best start: the earliest with the greatest probability in time, named with its first edge.
    best = max(plans, key=lambda p: p["deadline"]["probability"])
    assert page.data("plan-chart", "best") == best["time"]
    summary = page.text("plan-summary")
    hhmm = time.strftime("%H:%M", time.gmtime(best["time"]))
    assert f"best start {hhmm} UTC" in summary, summary
    assert f"{best['deadline']['probability']:.3f}" in summary, summary
    assert best["deadline"]["first_edge"] and f"first edge {best['deadline']['first_edge']}" in summary, summary
    legend = page.text("plan-legend")
    assert "deadline plan" in legend and "expected-time plan" in legend and "Pmax" in legend, legend
    # Three lines: Pmax, the expected-time plan and the deadline plan.
    assert page.driver.execute_script("return document.querySelectorAll('#plan-chart polyline').length") == 3
    page.shot("viewer-topo-deadline.png")

    # 1000 s: the default buckets of 96 start times would be more cells than the service
    # plans in one request, so the page asks for wider ones, and plots what the API answers.
    request = plan("1000")
    bucket = page.data("plan-chart", "bucket")
    assert bucket is not None and 1000 / 600 < bucket < 1000 / 400
    plans = service.post("/v1/topo/witham/plan", {**request, "deadline_secs": 1000, "bucket_secs": bucket})["plans"]
    assert all(p["deadline"]["bucket_secs"] == bucket for p in plans)
    assert page.data("plan-chart", "inTime") == [p["deadline"]["probability"] for p in plans]
    assert page.data("plan-chart", "minTime") == [p["deadline"]["min_time_probability"] for p in plans]
    assert "wider than the default" in page.text("plan-summary")

    # Invalid deadlines are refused in the page, naming what is wrong; nothing is sent.
    def refused(deadline, typed=False):
        before = plan_requests()
        if typed:  # what the number field cannot parse: its value is empty, its input bad
            field = page.driver.find_element("id", "plan-deadline")
            field.clear()
            field.send_keys(deadline)
        else:
            page.set_value("plan-deadline", deadline, "input")
        page.driver.find_element("id", "plan-run").click()
        give_up = time.time() + 30
        while not page.text("plan-error") and time.time() < give_up:
            time.sleep(0.05)
        error = page.text("plan-error")
        assert page.driver.execute_script("return document.getElementById('plan-chart').dataset.state") == "error"
        assert page.text("plan-summary") == "" and page.text("plan-legend") == ""
        time.sleep(0.3)
        assert plan_requests() == before, f"{deadline!r} was sent"
        return error

    for bad in ["-5", "0"]:
        error = refused(bad)
        assert f"{bad} is not a number of seconds > 0" in error, error
    error = refused("1e", typed=True)
    assert "not a number" in error, error

    # Beyond what the service plans (10^11 s): its reason, naming the field.
    page.set_value("plan-deadline", "1e12", "input")
    page.driver.find_element("id", "plan-run").click()
    give_up = time.time() + 30
    while "deadline_secs" not in page.text("plan-error") and time.time() < give_up:
        time.sleep(0.05)
    assert "field `deadline_secs`" in page.text("plan-error"), page.text("plan-error")
    page.expected_failures = 1

    # No deadline again: the Pmax chart, as before.
    request = plan("")
    assert page.text("plan-error") == ""
    assert page.data("plan-chart", "deadline") is None and page.data("plan-chart", "inTime") is None
    plans = service.post("/v1/topo/witham/plan", request)["plans"]
    assert page.data("plan-chart", "pmax") == [p["pmax"] for p in plans]
    assert page.data("plan-chart", "expected") == [p["expected_secs"] for p in plans]
    assert "Pmax (left axis)" in page.text("plan-legend")
    assert page.driver.execute_script("return document.querySelectorAll('#plan-chart polyline').length") == 2


def test_activity_map_shows_mean_and_deviation(page, service):
    page.open("activity")
    page.ready("activity-mean")
    page.ready("activity-std")
    t = page.data("activity-mean", "t")
    cell = page.data("activity-mean", "cell")
    answer = service.post("/v1/activity/atc/predict", {"t": t, "cell": cell})
    assert page.data("activity-mean", "values") == answer["mean"]
    assert page.data("activity-std", "values") == answer["std"]
    assert page.data("activity-mean", "shape") == answer["shape"]
    assert any(v is None for v in answer["mean"]), "the map's walls are masked"
    # The slider spans the training times (and a period beyond).
    info = service.get("/v1/activity/atc")
    later = int(info["t_range"][0]) + 5
    page.restart("activity-mean")
    page.set_value("activity-slider", str(later), "input")
    page.ready("activity-mean")
    page.ready("activity-std")
    assert page.data("activity-mean", "t") == later
    answer = service.post("/v1/activity/atc/predict", {"t": later, "cell": cell})
    assert page.data("activity-mean", "values") == answer["mean"]
    page.shot("viewer-activity.png")


def test_an_empty_service_says_what_to_do_and_a_dead_one_is_reported(page, tmp_path):
    process = subprocess.Popen(
        [str(BIN), "serve", "--data", str(tmp_path / "store"), "--listen", "127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = re.search(r"listening on (http://\S+)", process.stdout.readline()).group(1)
        page.driver.get("about:blank")
        page.driver.get(f"{url}/#models")
        deadline = time.time() + 30
        while page.driver.execute_script("return document.getElementById('model-chart').dataset.state") != "empty":
            assert time.time() < deadline, "the empty model list was not shown"
            time.sleep(0.1)
        assert page.text("model-title") == "No models yet"
        assert "chronomap client add" in page.text("model-summary")
        for tab, flag in [("grids", "--grid"), ("topo", "--topo"), ("activity", "--activity")]:
            page.driver.find_element("css selector", f"nav button[data-tab={tab}]").click()
            view = {"grids": "grid"}.get(tab, tab)
            deadline = time.time() + 30
            while not page.driver.execute_script(f"return !document.getElementById('{view}-empty').hidden"):
                assert time.time() < deadline, f"the {tab} tab does not say that nothing is served"
                time.sleep(0.1)
            assert flag in page.text(f"{view}-empty")
            assert page.driver.execute_script(f"return document.getElementById('{view}-body').hidden")
        page.shot("viewer-empty.png")
    finally:
        process.terminate()
        process.wait(timeout=30)
    # The service is gone: the next request says so instead of leaving the page blank.
    page.driver.find_element("css selector", "nav button[data-tab=models]").click()
    page.driver.execute_script("document.getElementById('model-search').value = ''")
    page.driver.execute_script("loaded.models = false; selectTab('models')")
    deadline = time.time() + 30
    while "does not answer" not in page.text("banner"):
        assert time.time() < deadline, f"no error shown: {page.text('banner')!r}"
        time.sleep(0.1)
    page.expected_failures = None  # the refused connections
