"""Diagnosing a fleet's logs in parallel on Dask, resumable and idempotent.

:func:`discover` turns a folder tree (``DIR/<robot_id>/<ISO date or date-time>.npz|.csv``) or a manifest
CSV (columns ``robot_id, time, path`` and optionally ``joints, robot_model``) into log entries.
:func:`diagnose_entry` is the per-log task a worker runs (single-threaded BLAS): it loads the log,
runs :func:`drake_est.diagnose.diagnose` and returns JSON-able findings and parameters, or the
one-line reason the log failed.  :func:`run_fleet` skips what the store already holds for the same
settings, submits the rest to a ``LocalCluster`` of processes (or an existing scheduler), and writes
each result from the client in its own transaction as it completes, so an interrupted run loses
nothing that was written and a restart does only the rest.  A worker that dies mid-task has its task
rescheduled by Dask; a task that keeps killing workers is reported as unfinished (not written) and
retried by the next run.
"""
from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import json
import os
import time
from pathlib import Path

from drake_est.errors import DataError
from drake_est.threads import single_thread_blas  # noqa: F401  (re-exported: drake_est.fleet.run.single_thread_blas)

LOG_SUFFIXES = (".npz", ".csv")
KNOWN_MODELS = ("generic", "irb140")
MANIFEST_COLUMNS = ("robot_id", "time", "path")

#: diagnosis settings of a fleet run (their hash is part of each stored log's identity)
DEFAULT_SETTINGS = {"seed": 0, "alpha": None, "min_gain": None, "simulate": False}


def software_version() -> str:
    import drake_est
    return str(getattr(drake_est, "__version__", "unknown"))


def settings_hash(settings: dict) -> str:
    """sha256 (16 hex digits) of the canonical JSON of the diagnosis settings."""
    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]


def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ----------------------------------------------------------------------------- discovery
def discover(source) -> list:
    """Log entries ``{robot_id, time, path, joints, robot_model}`` of a folder tree or a manifest CSV
    (times normalized to ISO; an unreadable time is kept as written and fails that log alone)."""
    entries = _discover(source)
    for e in entries:
        try:
            e["time"] = parse_time(e["time"])
        except DataError:
            pass
    return entries


def _discover(source) -> list:
    src = Path(source)
    if not src.exists():
        raise DataError(f"fleet source {src} does not exist (give a folder of robot folders or a manifest CSV)")
    if src.is_file():
        return _read_manifest(src)
    entries = []
    for rdir in sorted(p for p in src.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))):
        model = "auto"
        info = rdir / "robot.json"
        joints = ""
        if info.exists():
            try:
                d = json.loads(info.read_text())
            except json.JSONDecodeError as err:
                raise DataError(f"{info}: not valid JSON ({err})") from None
            model = str(d.get("model", "auto"))
            joints = ",".join(str(j) for j in d.get("joints", []))
        for f in sorted(rdir.iterdir()):
            if f.suffix.lower() in LOG_SUFFIXES:
                entries.append({"robot_id": rdir.name, "time": f.stem, "path": str(f), "joints": joints,
                                "robot_model": model})
    if not entries:
        raise DataError(f"{src}: no logs found (expected {src}/<robot_id>/<date>.npz or .csv)")
    return entries


def _read_manifest(path: Path) -> list:
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        cols = reader.fieldnames or []
        if not cols:
            raise DataError(f"manifest {path} is empty (expected a header line robot_id,time,path"
                            f"[,joints,robot_model] and one line per log)")
        missing = [c for c in MANIFEST_COLUMNS if c not in cols]
        if missing:
            raise DataError(f"manifest {path}: missing column(s) {', '.join(missing)} (have: {', '.join(cols)})")
        entries = []
        for k, row in enumerate(reader, start=2):
            if not row.get("path") or not row.get("robot_id") or not row.get("time"):
                raise DataError(f"manifest {path}: line {k} has an empty robot_id, time or path")
            p = Path(row["path"])
            if not p.is_absolute():
                p = path.parent / p
            entries.append({"robot_id": row["robot_id"].strip(), "time": row["time"].strip(), "path": str(p),
                            "joints": (row.get("joints") or "").strip(),
                            "robot_model": (row.get("robot_model") or "auto").strip() or "auto"})
    if not entries:
        raise DataError(f"manifest {path} lists no logs")
    return entries


def parse_time(text: str) -> str:
    """ISO date or date-time (``2026-05-12``, ``2026-05-12T08-30-00``) -> ISO string; DataError otherwise."""
    s = text.strip()
    try:
        return _dt.date.fromisoformat(s).isoformat()
    except ValueError:
        pass
    if len(s) > 10 and s[10] in "T_ ":
        for cand in (s[:10] + "T" + s[11:], s[:10] + "T" + s[11:].replace("-", ":")):
            try:
                return _dt.datetime.fromisoformat(cand).isoformat()
            except ValueError:
                continue
    raise DataError(f"log time '{text}' is not an ISO date or date-time (like 2026-05-12 or 2026-05-12T08-30-00)")


def _resolve_model(entry, log_meta) -> str:
    model = entry.get("robot_model") or "auto"
    if model == "auto":
        model = str(log_meta.get("robot", "generic"))
    if model in KNOWN_MODELS:
        return model
    if model.lower().endswith(".urdf"):
        if not Path(model).exists():
            raise DataError(f"robot model URDF {model} not found")
        return model
    raise DataError(f"unknown robot model '{model}' (use {', '.join(KNOWN_MODELS)} or a URDF path)")


def _joints(text):
    if not text:
        return None
    try:
        js = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise DataError(f"joints '{text}' must be comma-separated 1-based joint numbers") from None
    if any(j < 1 for j in js):
        raise DataError(f"joints '{text}' must be 1-based joint numbers")
    return js or None


# ----------------------------------------------------------------------------- per-log task
def extract_parameters(d: dict, robot_model: str) -> list:
    """Time-series points of one report dict (see the ``parameters`` table of the store)."""
    out = []
    ripple, freq, energy = {}, {}, {}
    payload = 0.0
    for f in d["findings"]:
        p = f.get("parameters", {})
        if f["effect"] == "motor_position_ripple":
            a = float(p.get("rms_amplitude", 0.0))
            if a > ripple.get(f["joint"], -1.0):
                ripple[f["joint"]] = a
                if "frequency_per_arm_rev" in p:
                    freq[f["joint"]] = float(p["frequency_per_arm_rev"])
        elif f["effect"] == "energy_dependent_friction" and "time_constant_s" in p:
            energy[f["joint"]] = float(p["time_constant_s"])
        elif f["effect"] == "payload" and "mass_kg" in p:
            payload = float(p["mass_kg"])
    for j, p in d["nominal"]["parameters"].items():
        j = int(j)
        out.append({"joint": j, "name": "coulomb_nm", "value": float(p["kc"])})
        out.append({"joint": j, "name": "viscous_nms", "value": float(p["kv"])})
        out.append({"joint": j, "name": "ripple_amplitude_nm", "value": ripple.get(j, 0.0)})
        if j in freq:
            out.append({"joint": j, "name": "ripple_frequency_per_rev", "value": freq[j]})
        if j in energy:
            out.append({"joint": j, "name": "energy_time_constant_s", "value": energy[j]})
    if robot_model != "generic":
        out.append({"joint": 0, "name": "payload_mass_kg", "value": payload})
    import math
    return [p for p in out if math.isfinite(p["value"])]


def _worker_name() -> str:
    try:
        from distributed import get_worker
        return str(get_worker().name)
    except Exception:
        return f"pid{os.getpid()}"


def diagnose_entry(entry: dict, settings: dict, sha: str | None = None) -> dict:
    """Diagnose one log (runs on a worker, single-threaded BLAS).  Never raises for a bad log:
    returns ``status="failed"`` with the one-line reason instead."""
    t0 = time.perf_counter()
    res = {"entry": entry, "settings": settings, "settings_hash": settings_hash(settings),
           "software_version": software_version(), "worker": _worker_name(), "findings": [], "parameters": []}
    try:
        res["file_sha256"] = sha or file_sha256(entry["path"])
    except OSError as err:
        res.update(file_sha256="missing", status="failed", error=f"cannot read {entry['path']}: {err.strerror}")
        return res
    try:
        with single_thread_blas():
            res.update(_diagnose(entry, settings))
        res["status"] = "ok"
    except Exception as err:  # a corrupt log must not stop the fleet: record the one-line reason
        from drake_est.errors import DrakeEstError
        msg = str(err).strip().splitlines()[0] if str(err).strip() else ""
        res["status"] = "failed"
        res["error"] = msg if isinstance(err, DrakeEstError) else f"{type(err).__name__}: {msg}"
    res["elapsed_s"] = time.perf_counter() - t0
    return res


def _diagnose(entry, settings) -> dict:
    from drake_est.data import load_log
    from drake_est.diagnose import diagnose
    parse_time(entry["time"])
    path = Path(entry["path"])
    limits = None
    if entry.get("robot_model") == "irb140":
        from drake_est.robots import irb140_metadata
        limits = irb140_metadata().limits_dict()
    log = load_log(path, limits=limits)
    model = _resolve_model(entry, log.meta)
    if model == "irb140" and limits is None:     # model read from the log itself: check against the limits
        from drake_est.robots import irb140_metadata
        log = load_log(path, limits=irb140_metadata().limits_dict())
    kw = {k: settings[k] for k in ("alpha", "min_gain") if settings.get(k) is not None}
    rep = diagnose(log, robot=model, joints=_joints(entry.get("joints")), seed=int(settings.get("seed", 0)),
                   simulate=bool(settings.get("simulate", False)), source=str(path), **kw)
    d = rep.to_dict()
    findings = [{"effect": f["effect"], "joint": f["joint"], "heldout_gain": f["gain"]["rmse_ratio"],
                 "p_value": f["evidence"]["p_value"], "parameters": f["parameters"],
                 "evidence": {k: v for k, v in f["evidence"].items() if isinstance(v, (int, float, str))}}
                for f in d["findings"]]
    return {"findings": findings, "parameters": extract_parameters(d, model), "resolved_model": model,
            "nominal_rmse": d["nominal"]["validation"]["rmse"], "duration_s": d["data"]["duration_s"]}


# ----------------------------------------------------------------------------- orchestration
def worker_env() -> dict:
    """Environment of worker processes: single-threaded BLAS (many small solves per log) and one thread per
    diagnosis (:mod:`drake_est.diagnose.parallel`): the workers already take one core each."""
    return {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "DRAKE_EST_DIAG_THREADS")}


def local_cluster(workers: int | None = None):
    """A ``LocalCluster`` of single-threaded worker processes, no dashboard."""
    from distributed import LocalCluster
    for k, v in worker_env().items():
        os.environ.setdefault(k, v)
    n = int(workers) if workers else (os.cpu_count() or 1)
    if n < 1:
        raise DataError(f"--workers must be at least 1, got {workers}")
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=40)


def run_fleet(source, store, scheduler: str | None = None, workers: int | None = None, settings: dict | None = None,
              client=None, show_progress: bool = True, limit: int | None = None) -> dict:
    """Diagnose every log of ``source`` (folder tree or manifest) not yet in ``store`` (path) with
    these ``settings``; returns counts.  ``client``: an existing ``distributed.Client``;
    ``scheduler``: an address to connect to; otherwise a ``LocalCluster`` of ``workers`` processes."""
    from drake_est.fleet.store import FleetStore
    from drake_est.progress import progress
    settings = dict(DEFAULT_SETTINGS, **(settings or {}))
    shash = settings_hash(settings)
    entries = discover(source)
    st = FleetStore(store)          # refuses a read-only store before any work starts
    t_start = time.perf_counter()
    try:
        done = st.done_keys(shash)
        todo, skipped, shas = [], 0, {}
        for e in entries:
            try:
                sha = file_sha256(e["path"])
            except OSError:
                sha = None
            # a file still missing that the store already holds as failed ("missing") is not retried either
            if (e["robot_id"], e["time"], sha or "missing") in done:
                skipped += 1
                continue
            shas[len(todo)] = sha
            todo.append(e)
        if limit is not None:
            todo = todo[:limit]
        sched_name = scheduler or (f"client {client.scheduler.address}" if client is not None else
                                   f"LocalCluster({workers or os.cpu_count()} processes)")
        run_id = st.start_run(shash, software_version(), sched_name, len(entries), skipped)
        counts = {"logs": len(entries), "skipped": skipped, "submitted": len(todo), "ok": 0, "failed": 0,
                  "duplicates": 0, "unfinished": 0, "unfinished_reasons": []}
        if todo:
            _run_dask(todo, shas, settings, st, run_id, counts, scheduler, workers, client, show_progress, progress)
        counts["elapsed_s"] = time.perf_counter() - t_start
        counts["logs_per_s"] = (counts["ok"] + counts["failed"]) / counts["elapsed_s"] if counts["elapsed_s"] else 0.0
        counts["run_id"] = run_id
        counts["settings_hash"] = shash
        return counts
    finally:
        st.close()


def _run_dask(todo, shas, settings, st, run_id, counts, scheduler, workers, client, show_progress, progress):
    from distributed import Client, as_completed
    cluster = own_client = None
    try:
        if client is None:
            if scheduler:
                try:
                    own_client = Client(scheduler, timeout="20s")
                except (OSError, TimeoutError, ValueError) as err:   # ValueError: a malformed address
                    raise DataError(f"cannot reach the Dask scheduler at {scheduler}: {err}") from None
            else:
                cluster = local_cluster(workers)
                own_client = Client(cluster)
            client = own_client
        futs = [client.submit(diagnose_entry, e, settings, shas[k], pure=False,
                              key=f"diagnose-{k}-{e['robot_id']}-{e['time']}-{os.getpid()}-{run_id}")
                for k, e in enumerate(todo)]
        bar = progress(total=len(futs), desc="fleet diagnose", leave=True)
        bar.unit = "log"
        try:
            for fut in as_completed(futs):
                try:
                    res = fut.result()
                except Exception as err:  # e.g. KilledWorker: not written, retried by the next run
                    counts["unfinished"] += 1
                    if len(counts["unfinished_reasons"]) < 5:
                        counts["unfinished_reasons"].append(f"{type(err).__name__}: {str(err)[:200]}")
                    bar.update(1)
                    continue
                if st.record(res, run_id):
                    counts["ok" if res["status"] == "ok" else "failed"] += 1
                else:
                    counts["duplicates"] += 1
                fut.release()
                bar.update(1)
        finally:
            bar.close()
            st.finish_run(run_id, counts["ok"], counts["failed"],
                          counts["submitted"] - counts["ok"] - counts["failed"] - counts["duplicates"])
    finally:
        if own_client is not None:
            own_client.close()
        if cluster is not None:
            cluster.close()
