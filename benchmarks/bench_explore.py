"""How fast the explorer answers a change of its inputs, driven as a person drives it.

The explorer's server runs in this process (``cosserat_channel.explorer.server.Running``) and is
warmed up first (kernels compiled, atlas read). Then each of ``eps, L, K, A, N`` is dragged
across its slider in ``--steps`` moves, every move a change:

- *server*: the requests the page sends for a change (the point, the line and, when ``eps L``
  changed, the map) sent at once, as the page sends them, over HTTP; a change is answered when
  all three are (an answer may be "pending": the work went to the background, and is counted);
- *browser* (when Chromium, chromedriver and selenium are installed): the page in headless
  Chromium, each slider moved by an ``input`` event; the page itself times each change from the
  event to the last answer drawn (``window.explore.changes``), so this includes the browser's
  parsing and drawing.

Side by side, the import cost of the page's server (``cosserat_channel.explorer.server``, standard
library) and of Panel, the field's default for such apps, when ``--panel-python`` names an
interpreter that has it (each in a fresh process, best and median of ``--imports`` runs).

Targets: a change answered within 100 ms (median) and 300 ms (worst), server and browser.

Run: ``.venv/bin/python benchmarks/bench_explore.py [--steps 20] [--panel-python PATH] [--json P]``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from cosserat_channel.explorer import server, answers
from cosserat_channel.measure import harness

MEDIAN_MS = 100.0
WORST_MS = 300.0


def moves(steps: int) -> list[dict]:
    """The changes: each parameter dragged across its slider, the others at figure 2's values."""
    out = []
    for name in ("eps", "L", "K", "A", "N"):
        s = answers.SLIDERS[name]
        if s["log"]:
            values = np.logspace(math.log10(s["lo"]), math.log10(s["hi"]), steps)
        else:
            values = np.linspace(s["lo"], s["hi"], steps)
        for v in values:
            out.append({name: f"{float(v):.5g}"})
    return out


def _post(url, kind, seq, form):
    body = {"client": "bench", "seq": seq, "form": form}
    req = urllib.request.Request(url + "api/" + kind, data=json.dumps(body).encode(),
                                 headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=600) as resp:
        return json.loads(resp.read())


def drive_server(url: str, changes: list[dict]) -> list[dict]:
    """Each change as the page sends it; its wall time until every request is answered."""
    form = server.default_form()
    rows, seq, last_eta = [], 0, None
    with ThreadPoolExecutor(3) as pool:
        for change in changes:
            form.update(change)
            kinds = ["point", "line"]
            key = (form["eps"], form["L"])
            if key != last_eta:
                kinds.append("map")
                last_eta = key
            seq += 1
            t0 = time.perf_counter()
            sent = dict(form)
            answers = list(pool.map(_post, [url] * len(kinds), kinds, [seq] * len(kinds),
                                    [sent] * len(kinds)))
            ms = 1e3 * (time.perf_counter() - t0)
            rows.append({"change": change, "ms": ms, "kinds": kinds,
                         "pending": [k for k, a in zip(kinds, answers) if "pending" in a],
                         "errors": [a["error"] for a in answers if "error" in a]})
            # let background work finish before the next move, as a person pauses
            for a in answers:
                while "pending" in a:
                    with urllib.request.urlopen(url + "api/job/" + a["pending"],
                                                timeout=600) as resp:
                        a = json.loads(resp.read())
    return rows


def drive_browser(url: str, changes: list[dict]) -> list[dict] | str:
    """The same changes in headless Chromium; the page's own timings, or why there are none."""
    from cosserat_channel.explorer import chromium

    reason = chromium.missing()
    if reason:
        return f"not measured: {reason}"
    driver, profile = chromium.driver()
    try:
        driver.get(url)
        _until(driver, "return window.explore.ready && window.explore.point && "
                       "window.explore.last.line && window.explore.idle()")
        rows = []
        for change in changes:
            (name, text), = change.items()
            n = driver.execute_script("return window.explore.changes.length")
            driver.execute_script(
                "const s = document.getElementById('sl-' + arguments[0]);"
                "const lo = Number(s.min), hi = Number(s.max);"
                "const x = Number(arguments[1]);"
                "s.value = arguments[2] ? Math.log10(x) : x;"
                "s.dispatchEvent(new Event('input'));",
                name, text, answers.SLIDERS[name]["log"])
            _until(driver, f"return window.explore.changes.length > {n}")
            last = driver.execute_script("return window.explore.changes.at(-1)")
            _until(driver, "return window.explore.idle()")
            rows.append({"change": change, "ms": last["ms"], "pending": last["pending"]})
        return rows
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _until(driver, script, timeout=120.0):
    t0 = time.monotonic()
    while not driver.execute_script(script):
        if time.monotonic() - t0 > timeout:
            raise RuntimeError(f"the page did not reach {script!r} in {timeout:g} s")
        time.sleep(0.01)


def import_seconds(python: str, module: str, runs: int) -> list[float] | None:
    """Seconds to import ``module`` in a fresh ``python`` (its own clock around the import)."""
    code = f"import time; t = time.perf_counter(); import {module}; print(time.perf_counter() - t)"
    out = []
    for _ in range(runs):
        p = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=600)
        if p.returncode != 0:
            return None
        out.append(float(p.stdout.strip()))
    return out


def summary(rows) -> tuple[float, float, int]:
    ms = [r["ms"] for r in rows]
    return statistics.median(ms), max(ms), sum(1 for r in rows if r["pending"])


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--steps", type=int, default=20, help="moves per slider (default 20)")
    ap.add_argument("--imports", type=int, default=3, help="fresh processes per import timing")
    ap.add_argument("--panel-python", metavar="PATH",
                    help="an interpreter with Panel installed, to time its import beside ours")
    ap.add_argument("--no-browser", action="store_true", help="skip the browser part")
    args = ap.parse_args()
    if args.steps < 2:
        ap.error("--steps must be at least 2")
    rec = harness.Record("bench_explore", args.json)
    print(f"load:     {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min; "
          f"{os.cpu_count()} cores)")
    rec.add("loadavg_before", list(os.getloadavg()))
    with tempfile.TemporaryDirectory() as out:
        app = server.Running(directory=out)
        try:
            t0 = time.perf_counter()
            app.explorer.warm.wait()
            print(f"warm-up (kernels loaded or compiled, atlas read): {time.perf_counter() - t0:.1f} s")
            changes = moves(args.steps)
            rows = drive_server(app.url, changes)
            med, worst, pend = summary(rows)
            errors = sum(len(r["errors"]) for r in rows)
            rec.add("server", {"changes": len(rows), "median_ms": med, "max_ms": worst,
                               "pending": pend, "errors": errors, "rows": rows})
            print(f"server:  {len(rows)} changes, median {med:.1f} ms, worst {worst:.1f} ms, "
                  f"{pend} went to the background, {errors} errors")
            browser = "not measured: --no-browser" if args.no_browser else \
                drive_browser(app.url, changes)
        finally:
            app.stop()
    verdicts = [rec.check(f"server: median <= {MEDIAN_MS:g} ms", med <= MEDIAN_MS, f"{med:.1f} ms"),
                rec.check(f"server: worst <= {WORST_MS:g} ms", worst <= WORST_MS, f"{worst:.1f} ms")]
    if isinstance(browser, str):
        print(f"browser: {browser}")
        verdicts.append(rec.check("browser: median and worst", None, browser))
    else:
        bmed, bworst, bpend = summary(browser)
        rec.add("browser", {"changes": len(browser), "median_ms": bmed, "max_ms": bworst,
                            "pending": bpend, "rows": browser})
        print(f"browser: {len(browser)} changes, median {bmed:.1f} ms, worst {bworst:.1f} ms, "
              f"{bpend} went to the background")
        verdicts += [rec.check(f"browser: median <= {MEDIAN_MS:g} ms", bmed <= MEDIAN_MS,
                               f"{bmed:.1f} ms"),
                     rec.check(f"browser: worst <= {WORST_MS:g} ms", bworst <= WORST_MS,
                               f"{bworst:.1f} ms")]
    ours = import_seconds(sys.executable, "cosserat_channel.explorer.server", args.imports)
    imports = {"explore_server": ours}
    line = f"import:  cosserat_channel.explorer.server best {min(ours):.2f} s, median " \
           f"{statistics.median(ours):.2f} s"
    if args.panel_python:
        panel = import_seconds(args.panel_python, "panel", args.imports)
        imports["panel"] = panel
        if panel:
            line += (f"; panel best {min(panel):.2f} s, median {statistics.median(panel):.2f} s "
                     f"({statistics.median(panel) / statistics.median(ours):.1f}x)")
        else:
            line += f"; panel: cannot import with {args.panel_python}"
    rec.add("imports", imports)
    print(line)
    print(f"load:     {' '.join(f'{x:.2f}' for x in os.getloadavg())} (after)")
    rec.add("loadavg_after", list(os.getloadavg()))
    for v in verdicts:
        print(v.line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
