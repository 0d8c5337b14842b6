"""Synthetic plan.json documents for the figure tests: n aircraft on smooth paths through the thesis's wall."""

from __future__ import annotations

import html as html_lib
import json
import re
import subprocess
from dataclasses import asdict
from pathlib import Path

import numpy as np

from mal_planner.obstacles import Gate, Superquadric, wall_with_hole


def synthetic_plan(n: int, optimal: bool = True) -> dict:
    """A plan.json document: aircraft k starts on an arc at y ~ 5.5, passes the hole at y = 3, lands at 0."""
    wall = wall_with_hole("wall", 1, 3.0, 0.001, ((-3.0, 3.0), (0.0, 0.3)), ((-1.0, 1.0), (0.1, 0.2)))
    gate = Gate("wall-hole", 1, 3.0, -1, ((-1.0, 1.0), (0.1, 0.2)), 0.0, -np.pi / 2)
    zone = Superquadric("zone", (2.0, 1.5, 0.1), (0.4, 0.6, 0.1), 2)
    aircraft = []
    for k in range(n):
        x0 = -2.6 + 5.2 * k / max(n - 1, 1)
        gate_t, land_t = 60.0 + 12.0 * k, 135.0 + 12.0 * k
        t = np.arange(0.0, land_t, 0.25)
        t = np.append(t, land_t)
        s = np.clip(t / gate_t, 0.0, 1.0)
        after = np.clip((t - gate_t) / (land_t - gate_t), 0.0, 1.0)
        x = np.where(t <= gate_t, x0 * (1 - s) ** 2 + 0.1 * np.sin(3 * s + k) * s * (1 - s), 0.0)
        y = np.where(t <= gate_t, 5.5 - 2.5 * s + 0.3 * np.sin(np.pi * s) * (k % 3 - 1), 3.0 * (1 - after))
        z = np.where(t <= gate_t, 0.25 - 0.1 * s + 0.02 * np.sin(np.pi * s) * (k % 2), 0.15 * (1 - after))
        heading = np.unwrap(np.arctan2(np.gradient(y, t), np.gradient(x, t)))
        gamma = np.arctan(np.gradient(z, t) / 0.04)
        n_h = 0.3 * np.sin(t / 15.0 + k) * (t <= gate_t)
        phase = np.searchsorted([gate_t, land_t], t, side="left")
        traj = {"t": t.tolist(), "x": x.tolist(), "y": y.tolist(), "z": z.tolist(), "gamma": gamma.tolist(),
                "heading": heading.tolist()}
        if optimal:
            traj |= {"n_h": n_h.tolist(), "n_v": np.cos(gamma).tolist(), "phase": phase.tolist()}
        wp_t = t[::40]
        aircraft.append({
            "callsign": f"C{k + 1:02d}", "order": k + 1, "gate_time_s": gate_t if optimal else None,
            "landing_time_s": land_t,
            "initial": {"waypoints": {"t": wp_t.tolist(), "x": x[::40].tolist(), "y": y[::40].tolist(),
                                      "z": z[::40].tolist()},
                        "direct_path": [[x0, 5.5, 0.25], [0.0, 3.0, 0.15], [0.0, 0.0, 0.0]]},
            "limits": {"n_h": [-2.0, 2.0], "n_v": [0.0, 2.0], "bank_angle_max": float(np.radians(45 - (k % 2) * 15))},
            "trajectory": traj,
        })
    return {
        "schema": "mal-planner/plan", "version": 1, "status": "optimal" if optimal else "initial_guess",
        "verified": optimal, "landing_order": [a["callsign"] for a in aircraft],
        "scenario": {"name": f"synthetic{n}", "source": "<test>", "airspace": [[-3, 3], [0, 6], [0, 0.3]],
                     "runway": [0, 0, 0, 0, -np.pi / 2], "separation_nm": 0.25,
                     "obstacles": [asdict(o) for o in (*wall, zone)], "gates": [asdict(gate)]},
        "optimizer": {"phases": []}, "verification": None, "aircraft": aircraft,
    }


CHROMIUM = "/usr/bin/chromium"
_CATCH = ("<script>window.__errors=[];window.addEventListener('error',function(e){"
          "window.__errors.push(String(e.message||e))});</script>")
_PROBE = """<script>
window.addEventListener('load', function () {
  var out = document.createElement('pre'); out.id = 'probe';
  function done(o) { out.textContent = JSON.stringify(o); document.body.appendChild(out); }
  try {
    var gd = document.querySelector('.plotly-graph-div');
    var names = ((gd && gd._transitionData && gd._transitionData._frames) || []).map(function (f) { return f.name; });
    var mid = names[Math.floor(names.length / 2)];
    Plotly.animate(gd, [mid], {mode: 'immediate', frame: {duration: 0, redraw: true}, transition: {duration: 0}})
      .then(function () {
        done({errors: window.__errors, frames: names.length, frame: mid,
              markers: gd.data.filter(function (t) { return t.mode === 'markers+text'; })
                              .map(function (t) { return [t.x, t.y, t.z]; }),
              canvas: !!document.querySelector('.gl-container canvas'), svg: !!document.querySelector('.main-svg')});
      }, function (e) { done({errors: window.__errors.concat([String(e)])}); });
  } catch (e) { done({errors: window.__errors.concat([String(e)])}); }
});
</script>"""


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    """Headless Chromium with a fresh profile, no network services, WebGL on SwiftShader."""
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={profile}", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
           "--virtual-time-budget=5000", "--window-size=1200,800", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=90)


def browser_probe(html: Path, work: Path) -> dict:
    """Open a probed copy of ``html`` in headless Chromium; return what the page reported.

    The copy records every JavaScript error and, once loaded, moves the time slider to the middle frame
    and reports the aircraft markers' positions there. ``{"errors": [...]}`` says what went wrong.
    """
    text = html.read_text(encoding="utf-8")
    probed = work / "probed.html"
    probed.write_text(text.replace("<head>", "<head>" + _CATCH, 1).replace("</body>", _PROBE + "</body>", 1),
                      encoding="utf-8")
    run = chromium(["--dump-dom", probed.as_uri()], work / "profile-dom")
    match = re.search(r'<pre id="probe">(.*?)</pre>', run.stdout, re.S)
    if match is None:
        return {"errors": [f"page never finished loading (chromium exit {run.returncode}): {run.stderr[-500:]}"]}
    report = json.loads(html_lib.unescape(match.group(1)))
    if "WebGL is not supported" in re.sub(r"<script.*?</script>", "", run.stdout, flags=re.S):
        report["errors"].append("WebGL is not available")
    return report


def screenshot(html: Path, png: Path, work: Path) -> np.ndarray:
    """Screenshot of ``html`` (1200 x 800) as an (h, w, channels) array."""
    import matplotlib.image

    chromium([f"--screenshot={png}", html.as_uri()], work / "profile-shot")
    return matplotlib.image.imread(png)
