"""Static fleet report: ``index.html`` (no server; plots inline as base64 PNG) and ``report.json``.

Contents: counts; a robots x joints overview coloured by the latest finding and the warnings; the
ranked warnings; per robot-joint trend plots (the parameter series, the trend-filter line, the
one-switch fit and the change date) for every warning; and the logs that failed with their reason.
The store is read only through its SQL schema (:mod:`drake_est.fleet.store`).
"""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from drake_est.fleet.trends import PARAMETERS, days_since, fleet_trends

COLOURS = {"warning": "#e06666", "explained": "#f6b26b", "finding": "#ffd966", "healthy": "#93c47d",
           "no data": "#cccccc"}
MAX_PLOTS = 40


def overview(store, trends) -> dict:
    """{robot_id: {"joints": {joint: {"state", "label"}}, "failed": n, "logs": n}} from the store."""
    rows = store.query("SELECT robot_id, COUNT(*), SUM(status = 'failed') FROM logs GROUP BY robot_id ORDER BY robot_id")
    ov = {rid: {"logs": int(n), "failed": int(f or 0), "joints": {}} for rid, n, f in rows}
    for rid, j in store.query("SELECT DISTINCT l.robot_id, p.joint FROM parameters p JOIN logs l "
                              "ON l.log_id = p.log_id WHERE p.joint > 0"):
        ov[rid]["joints"][int(j)] = {"state": "healthy", "label": ""}
    # latest ok log per robot: its findings
    latest = store.query("SELECT l.robot_id, f.joint, f.effect FROM logs l JOIN findings f ON f.log_id = l.log_id "
                         "WHERE l.status = 'ok' AND l.log_time = (SELECT MAX(log_time) FROM logs l2 "
                         "WHERE l2.robot_id = l.robot_id AND l2.status = 'ok')")
    for rid, j, eff in latest:
        cell = ov[rid]["joints"].setdefault(int(j), {"state": "healthy", "label": ""})
        cell["state"] = "finding"
        cell["label"] = eff
    for key, state in (("explained", "explained"), ("warnings", "warning")):
        for w in trends[key]:
            joints = ov[w["robot_id"]]["joints"]
            targets = [w["joint"]] if w["joint"] in joints else list(joints)
            for j in targets:
                joints[j] = {"state": state, "label": w["cause"]}
    return ov


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode()


def trend_plot(series_entries, change_date=None) -> str:
    """Base64 PNG: the series of one robot-joint (one panel per parameter) with trend and change."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = len(series_entries)
    fig, axes = plt.subplots(n, 1, figsize=(6.5, 1.8 * n + 0.4), sharex=True, squeeze=False)
    origin = min(min(e["times"]) for e in series_entries)
    for ax, e in zip(axes[:, 0], series_entries):
        t = days_since(e["times"], origin)
        ax.plot(t, e["values"], "o", ms=3, color="0.3", label="per log")
        if "trend" in e:
            ax.plot(t, e["trend"], "-", color="tab:blue", lw=1.2, label="trend filter (7.5)")
        if "fit" in e:
            ax.plot(t, e["fit"], "-", color="tab:red", lw=1.2, label="one-switch fit (7.8)")
        if "change" in e:
            ax.axvline(days_since([e["change"]["time"]], origin)[0], color="tab:red", ls="--", lw=1)
        unit = PARAMETERS.get(e["parameter"], (None,) * 4 + ("",))[4]
        ax.set_ylabel(f"{e['parameter'].rsplit('_', 1)[0]}\n[{unit}]" if unit else e["parameter"], fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel(f"days since {origin[:10]}", fontsize=8)
    out = _png(fig)
    plt.close(fig)
    return out


def build_report(store, out_dir, settings_hash: str | None = None) -> dict:
    """Write ``out_dir/index.html`` and ``out_dir/report.json``; returns the JSON dict."""
    from drake_est.jsonutil import dump_json
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tr = fleet_trends(store, settings_hash)
    ov = overview(store, tr)
    counts = store.counts()
    failed = [{"robot_id": r, "time": t, "path": p, "error": e} for r, t, p, e in
              store.query("SELECT robot_id, log_time, path, error FROM logs WHERE status = 'failed' "
                          "ORDER BY robot_id, log_time")]
    by_rj = {}
    for e in tr["series"]:
        by_rj.setdefault((e["robot_id"], e["joint"]), []).append(e)
    plots = []
    for w in (tr["warnings"] + tr["explained"])[:MAX_PLOTS]:
        key = (w["robot_id"], w["joint"])
        ents = [e for e in by_rj.get(key, []) if e["parameter"] in PARAMETERS]
        if w["joint"] == 0:   # the whole robot: payload plus each joint's Coulomb level
            ents += [e for (r, j), es in by_rj.items() if r == w["robot_id"] and j > 0
                     for e in es if e["parameter"] == "coulomb_nm"]
        if ents:
            plots.append({"title": w["text"], "png": trend_plot(ents)})
    report = {"counts": counts, "warnings": [_clean(w) for w in tr["warnings"]],
              "explained": [_clean(w) for w in tr["explained"]], "failed_logs": failed,
              "overview": {r: {"logs": v["logs"], "failed": v["failed"],
                               "joints": {str(j): c for j, c in v["joints"].items()}} for r, v in ov.items()}}
    dump_json(_finite(report), out / "report.json")
    (out / "index.html").write_text(_html(report, ov, plots))
    return report


def _clean(w):
    return {k: v for k, v in w.items() if k not in ("fit",)}


def _finite(x):
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def _html(rep, ov, plots) -> str:
    e = html.escape
    c = rep["counts"]
    maxj = max([max(v["joints"], default=0) for v in ov.values()] + [1])
    L = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>drake_est fleet report</title>",
         "<style>body{font-family:sans-serif;margin:1.5em;max-width:1100px}table{border-collapse:collapse}"
         "td,th{border:1px solid #999;padding:2px 6px;font-size:12px}td.cell{width:90px;text-align:center}"
         ".legend span{padding:2px 8px;margin-right:6px;font-size:12px}</style></head><body>",
         "<h1>Fleet report</h1>",
         f"<p>{c['robots']} robots, {c['logs']} logs diagnosed ({c['ok']} ok, {c['failed']} failed), "
         f"{c['findings']} findings; <b>{len(rep['warnings'])} warnings</b>.</p>",
         "<h2>Warnings (ranked by signal-to-noise)</h2>"]
    if rep["warnings"]:
        L.append("<table><tr><th>#</th><th>warning</th><th>cause</th><th>date</th><th>S/N</th></tr>")
        for w in rep["warnings"]:
            L.append(f"<tr><td>{w['rank']}</td><td>{e(w['text'])}</td><td>{e(w['cause'])}</td><td>{e(w['date'])}</td>"
                     f"<td>{w['snr']:.1f}</td></tr>")
        L.append("</table>")
    else:
        L.append("<p>No parameter changed significantly.</p>")
    if rep["explained"]:
        L.append("<h3>Changes explained by another change</h3><ul>")
        L += [f"<li>{e(w['text'])} &mdash; {e(w['explained_by'])}</li>" for w in rep["explained"]]
        L.append("</ul>")
    L.append("<h2>Robots &times; joints</h2><p class='legend'>"
             + "".join(f"<span style='background:{col}'>{e(k)}</span>" for k, col in COLOURS.items()) + "</p>")
    L.append("<table><tr><th>robot</th>" + "".join(f"<th>joint {j}</th>" for j in range(1, maxj + 1))
             + "<th>logs</th><th>failed</th></tr>")
    for rid, v in ov.items():
        row = [f"<tr><td>{e(rid)}</td>"]
        for j in range(1, maxj + 1):
            cell = v["joints"].get(j, {"state": "no data", "label": ""})
            row.append(f"<td class='cell' style='background:{COLOURS[cell['state']]}' title='{e(cell['state'])}'>"
                       f"{e(cell['label'].replace('_', ' '))}</td>")
        row.append(f"<td>{v['logs']}</td><td>{v['failed']}</td></tr>")
        L.append("".join(row))
    L.append("</table>")
    if plots:
        L.append("<h2>Trends of the changed joints</h2>")
        for p in plots:
            L.append(f"<h3>{e(p['title'])}</h3><img alt='{e(p['title'])}' src='data:image/png;base64,{p['png']}'>")
    if rep["failed_logs"]:
        L.append("<h2>Logs that failed</h2><table><tr><th>robot</th><th>time</th><th>reason</th></tr>")
        L += [f"<tr><td>{e(f['robot_id'])}</td><td>{e(f['time'])}</td><td>{e(f['error'] or '')}</td></tr>"
              for f in rep["failed_logs"]]
        L.append("</table>")
    L.append("<p><small>drake_est fleet report; the numbers are in report.json.</small></p></body></html>")
    return "\n".join(L)
