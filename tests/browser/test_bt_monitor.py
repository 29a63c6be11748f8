"""The viewer's "Behavior trees" tab, driven in a real browser (Chromium through WebDriver),
against trees run by the real BehaviorTree.CPP 4.8.2 with its own Groot2Publisher.

Two trees are started with `tests/bt/btcpp_groot2_tree.py` (43 nodes, past the 20 of Groot2's
free edition, and 12 nodes) on free ports, and `chronomap serve --bt-monitor` watches them and
a third port where nothing runs. The test waits until the page has drawn each tree, compares
the nodes it drew with the API's, watches the statuses change, reads the timeline of recorded
transitions and the blackboards, sees the third monitor reported as not connected and a tree
that stops and starts again reported and found again; it saves a screenshot and fails on any
JavaScript error in the browser console.

Run (from the repository root, after `cargo build`):

    target/browser-venv/bin/python -m pytest -q tests/browser/test_bt_monitor.py

Environment: as tests/browser/test_viewer.py, and CHRONOMAP_BT_PYTHON (a Python with
behaviortreepy 0.1.4; default target/bt-venv/bin/python). Without it the tests skip, unless
CHRONOMAP_REQUIRE_BT=1 or CHRONOMAP_REQUIRE_BROWSER=1 (as in CI).
"""

import base64
import json
import os
import re
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(os.environ.get("CHRONOMAP_BIN", ROOT / "target" / "debug" / "chronomap"))
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver")
SHOTS = Path(os.environ.get("CHRONOMAP_SCREENSHOTS", ROOT / "target" / "browser-screenshots"))
BT_PYTHON = Path(os.environ.get("CHRONOMAP_BT_PYTHON", ROOT / "target" / "bt-venv" / "bin" / "python"))
TREE_SCRIPT = ROOT / "tests" / "bt" / "btcpp_groot2_tree.py"
REQUIRED = (os.environ.get("CHRONOMAP_REQUIRE_BROWSER") == "1"
            or os.environ.get("CHRONOMAP_REQUIRE_BT") == "1")


def missing(what):
    if REQUIRED:
        pytest.fail(f"{what} (CHRONOMAP_REQUIRE_BROWSER=1 or CHRONOMAP_REQUIRE_BT=1)")
    pytest.skip(what)


def free_port_pair():
    """A port p on 127.0.0.1 with p + 1 free too (a Groot2 publisher binds both)."""
    for _ in range(100):
        with socket.socket() as first:
            first.bind(("127.0.0.1", 0))
            port = first.getsockname()[1]
            if port >= 65535:
                continue
            with socket.socket() as second:
                try:
                    second.bind(("127.0.0.1", port + 1))
                except OSError:
                    continue
        return port
    raise AssertionError("no two free ports in a row on 127.0.0.1")


class Tree:
    """A BehaviorTree.CPP tree with Groot2Publisher on `port`, ticking every 50 ms."""

    def __init__(self, port, name):
        self.port, self.name = port, name
        self.process = None

    def start(self):
        self.process = subprocess.Popen(
            [str(BT_PYTHON), str(TREE_SCRIPT), "--port", str(self.port), "--tree", self.name,
             "--seconds", "600"], stdout=subprocess.PIPE, text=True)
        line = self.process.stdout.readline()
        assert line.startswith("ready"), f"the {self.name} tree did not start: {line!r}"

    def stop(self):
        if self.process:
            self.process.kill()
            self.process.wait(timeout=30)
            self.process = None


def get(url):
    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return json.load(r)
    except urllib.error.HTTPError as e:
        raise AssertionError(f"GET {url}: {e.code} {e.read().decode()}") from None


def wait_for(what, check, timeout=60):
    deadline = time.time() + timeout
    while time.time() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"{what}: not within {timeout} s")


@pytest.fixture(scope="module")
def service():
    if not BIN.exists():
        missing(f"{BIN} is not built (cargo build)")
    if not BT_PYTHON.exists():
        missing(f"no Python with BehaviorTree.CPP at {BT_PYTHON} (CHRONOMAP_BT_PYTHON)")
    work = Path(tempfile.mkdtemp(prefix="chronomap-bt-monitor-"))
    patrol = Tree(free_port_pair(), "patrol")
    inspect = Tree(free_port_pair(), "inspect")
    nobody = free_port_pair()
    process = None
    try:
        patrol.start()
        inspect.start()
        process = subprocess.Popen(
            [str(BIN), "serve", "--data", str(work / "store"), "--listen", "127.0.0.1:0",
             "--bt-monitor", f"patrol=127.0.0.1:{patrol.port}",
             "--bt-monitor", f"inspect=127.0.0.1:{inspect.port}",
             "--bt-monitor", f"127.0.0.1:{nobody}"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = process.stdout.readline()
        match = re.search(r"listening on (http://\S+)", line)
        assert match, f"the service did not start: {line}{process.stderr.read()}"

        class Service:
            url = match.group(1)
            trees = {"patrol": patrol, "inspect": inspect}
            nobody_id = f"127.0.0.1:{nobody}"

        yield Service
    finally:
        if process:
            process.terminate()
            process.wait(timeout=30)
        patrol.stop()
        inspect.stop()
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
    # Headless, and no connection anywhere but the service on loopback; wide enough for two
    # trees side by side.
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--disable-dev-shm-usage", "--window-size=1800,1100",
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
    """The Behavior trees tab, with the console checked after the test: no JavaScript error,
    and no failed request (unless the test says `page.expected_failures = None`)."""
    browser.get_log("browser")

    class Page:
        driver = browser
        expected_failures = 0

        def open(self):
            browser.get("about:blank")
            browser.get(f"{service.url}/#bt")

        def script(self, code, *args):
            return browser.execute_script(code, *args)

        def state(self, element_id):
            return self.script("const e = document.getElementById(arguments[0]); return e && e.dataset.state",
                               element_id)

        def ready(self, element_id, timeout=60):
            wait_for(f"#{element_id} drawn", lambda: self.state(element_id) == "ready", timeout)

        def data(self, element_id, key):
            text = self.script("return document.getElementById(arguments[0]).dataset[arguments[1]]",
                               element_id, key)
            return None if text is None else json.loads(text)

        def panel(self, monitor_id):
            """The index of the panel of a monitor."""
            return self.script(
                "return [...document.querySelectorAll('.bt-monitor')].findIndex(p => p.dataset.monitor === arguments[0])",
                monitor_id)

        def connection(self, i):
            return self.script("return document.getElementById(arguments[0]).dataset.connection", f"bt-monitor-{i}")

        def shot(self, name):
            SHOTS.mkdir(parents=True, exist_ok=True)
            width, height = self.script(
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


STATUSES = {"idle", "running", "success", "failure", "skipped",
            "idle:running", "idle:success", "idle:failure", "idle:skipped"}


def test_every_node_of_both_trees_is_drawn_and_statuses_change(page, service):
    page.open()
    listed = [m["id"] for m in get(f"{service.url}/v1/bt/monitors")["monitors"]]
    assert listed == ["patrol", "inspect", service.nobody_id]
    for name, nodes in [("patrol", 43), ("inspect", 12)]:
        i = page.panel(name)
        page.ready(f"bt-tree-{i}")
        view = get(f"{service.url}/v1/bt/monitors/{name}")
        assert view["state"] == "connected"
        assert len(view["tree"]["nodes"]) == nodes
        # The page drew exactly the API's nodes: uids, names and types, one box each.
        drawn = page.data(f"bt-tree-{i}", "nodes")
        assert sorted(map(tuple, drawn)) == sorted(
            (n["uid"], n["name"], n["type"]) for n in view["tree"]["nodes"])
        boxes = page.script(
            "return [...document.querySelectorAll('#' + arguments[0] + ' g.bt-node')].map(g => +g.dataset.uid)",
            f"bt-tree-{i}")
        assert sorted(boxes) == sorted(n["uid"] for n in view["tree"]["nodes"])
        assert page.connection(i) == "connected"
    # Patrol's main tree, its Dock subtree below the SubTree node, and a name the tree gave.
    i = page.panel("patrol")
    names = {uid: name for uid, name, _ in page.data(f"bt-tree-{i}", "nodes")}
    assert names[1] == "patrol_round" and names[5] == "dock" and names[6] == "docking"
    # Statuses change while the trees tick: the page applies the service's events.
    first = page.data(f"bt-tree-{i}", "statuses")
    assert set(first) == {str(uid) for uid in names}
    changes0 = page.data(f"bt-tree-{i}", "changes")
    seen = set()

    def changed():
        now = page.data(f"bt-tree-{i}", "statuses")
        seen.update(now.values())
        return page.data(f"bt-tree-{i}", "changes") > changes0 + 20 and now != first and len(seen) >= 4

    wait_for("statuses changing on the page", changed, timeout=30)
    assert seen <= STATUSES, seen
    # Box colours follow the statuses: a running node is orange, a failed-then-idle one pale red.
    fills = page.script(
        "return [...document.querySelectorAll('#' + arguments[0] + ' g.bt-node')].map(g => [g.dataset.status, g.querySelector('rect').getAttribute('fill')])",
        f"bt-tree-{i}")
    assert all(fill == "#f0a020" for status, fill in fills if status == "running")


def test_timeline_shows_recorded_transitions(page, service):
    page.open()
    i = page.panel("patrol")
    page.ready(f"bt-tree-{i}")
    page.ready(f"bt-timeline-{i}", timeout=30)

    def enough():
        counts = page.data(f"bt-timeline-{i}", "counts")
        return counts if {"running", "success", "failure"} <= set(counts) else None

    counts = wait_for("running, success and failure in the timeline", enough, timeout=30)
    rows = page.data(f"bt-timeline-{i}", "rows")
    names = {uid for uid, _, _ in page.data(f"bt-tree-{i}", "nodes")}
    assert rows and set(rows) <= names
    # The service's numbers: every transition is of a node of the tree, in time order.
    answer = get(f"{service.url}/v1/bt/monitors/patrol/transitions")
    times = [t["time"] for t in answer["transitions"]]
    assert len(times) > 50 and times == sorted(times)
    assert {t["uid"] for t in answer["transitions"]} <= names
    assert answer["recording_since"] is not None
    assert sum(counts.values()) > 20
    bars = page.script("return document.querySelectorAll('#' + arguments[0] + ' rect[data-status]').length",
                       f"bt-timeline-{i}")
    assert bars > 10
    # The whole tab, with both trees, their timelines and blackboards (docs/img/bt-monitor.png).
    for k in range(2):
        page.ready(f"bt-timeline-{k}", timeout=30)
        page.ready(f"bt-blackboard-{k}", timeout=30)
    page.shot("bt-monitor.png")


def test_blackboards_are_shown(page, service):
    page.open()
    for name, board, key, expected in [("patrol", "Patrol", "robot", "tiago"),
                                       ("inspect", "Inspect", "robot", "tiago")]:
        i = page.panel(name)
        page.ready(f"bt-blackboard-{i}", timeout=30)
        boards = page.data(f"bt-blackboard-{i}", "blackboards")
        assert boards[board][key] == expected
        assert isinstance(boards[board]["round"], int) and boards[board]["round"] >= 1
        cell = page.script(
            "const t = document.querySelector(`#${arguments[0]} table[data-blackboard='${arguments[1]}'] tr[data-key='${arguments[2]}']`);"
            "return t && t.children[1].textContent", f"bt-blackboard-{i}", board, key)
        assert cell == expected
    # The subtree's own blackboard, under its path, once the Dock subtree has run (every
    # 5th round).
    i = page.panel("patrol")
    wait_for("the dock blackboard", lambda: "dock_station" in (page.data(f"bt-blackboard-{i}", "blackboards") or {}).get("dock", {}), 30)
    assert page.data(f"bt-blackboard-{i}", "blackboards")["dock"]["dock_station"] == "tiago"


def test_a_monitor_without_publisher_says_so_and_a_restarted_tree_is_found_again(page, service):
    page.expected_failures = None  # a blackboard read may meet the tree while it is gone
    page.open()
    i = page.panel(service.nobody_id)
    wait_for("the error of the monitor without publisher",
             lambda: "did not answer" in page.script(
                 "return document.querySelector('#bt-monitor-' + arguments[0] + ' .error').textContent", i), 30)
    assert page.connection(i) == "connecting"
    assert page.state(f"bt-tree-{i}") == "waiting"
    badge = page.script("return document.querySelector('#bt-monitor-' + arguments[0] + ' .bt-badge').textContent", i)
    assert badge.startswith("connecting to 127.0.0.1:")
    # The inspect tree stops: its panel says disconnected; it starts again: connected again.
    j = page.panel("inspect")
    page.ready(f"bt-tree-{j}")
    tree = service.trees["inspect"]
    tree.stop()
    wait_for("inspect disconnected", lambda: page.connection(j) == "disconnected", 30)
    summary = get(f"{service.url}/v1/bt/monitors/inspect")
    assert summary["state"] == "disconnected" and "did not answer" in summary["error"]
    tree.start()
    wait_for("inspect connected again", lambda: page.connection(j) == "connected", 30)
    after = get(f"{service.url}/v1/bt/monitors/inspect")
    assert after["reconnects"] == 1 and after["error"] is None
    page.ready(f"bt-tree-{j}")
    assert len(page.data(f"bt-tree-{j}", "nodes")) == 12
