"""The fleet store: an SQLite file (standard library) that any SQLite client can open.

Schema (``SCHEMA_VERSION`` 1; the report reads the store only through these tables):

``meta(key TEXT PRIMARY KEY, value TEXT)``
    ``schema_version``, ``created_by``.
``logs``: one row per diagnosed log and settings.
    ``log_id INTEGER PRIMARY KEY``, ``robot_id TEXT``, ``log_time TEXT`` (ISO date/time of the log),
    ``path TEXT``, ``robot_model TEXT`` (generic, irb140 or a URDF path), ``joints TEXT`` (comma-separated,
    1-based), ``file_sha256 TEXT`` (content of the log file), ``settings_hash TEXT``, ``settings_json TEXT``,
    ``software_version TEXT``, ``status TEXT`` (``ok`` | ``failed``: bad input, kept and skipped on a rerun),
    ``error TEXT`` (the one-line reason of a failure), ``n_findings INTEGER``, ``nominal_rmse REAL``
    [N m], ``duration_s REAL`` (log length), ``elapsed_s REAL`` (diagnosis time on the worker),
    ``worker TEXT``, ``run_id INTEGER``, ``finished_at TEXT``;
    ``UNIQUE(robot_id, log_time, file_sha256, settings_hash)``: a log already diagnosed with the same
    settings is never diagnosed or written again.
``findings``: one row per finding of a log.
    ``log_id`` (-> logs), ``rank INTEGER`` (1 = most important), ``effect TEXT`` (the diagnosis
    vocabulary), ``joint INTEGER`` (1-based), ``heldout_gain REAL`` (nominal / extended held-out RMSE),
    ``p_value REAL``, ``parameters_json TEXT``, ``evidence_json TEXT``; primary key ``(log_id, rank)``.
``parameters``: the identified parameters as long-form time-series points.
    ``log_id``, ``joint INTEGER`` (1-based; 0 = the whole robot, e.g. the payload), ``name TEXT``,
    ``value REAL``; primary key ``(log_id, joint, name)``.  Names: ``coulomb_nm``, ``viscous_nms``,
    ``ripple_amplitude_nm`` (0 when no ripple was found), ``ripple_frequency_per_rev`` (per arm
    revolution, when found), ``energy_time_constant_s`` (when found), ``payload_mass_kg`` (joint 0;
    0 when no payload was found; IRB 140 and URDF robots only).
``runs``: one row per ``fleet diagnose`` run: ``run_id``, ``started_at``, ``finished_at``,
    ``settings_hash``, ``software_version``, ``scheduler``, ``n_logs``, ``n_skipped``, ``n_ok``,
    ``n_failed``, ``n_unfinished``.

Results are written by the client only, one transaction per log (log row, findings and parameters
together), so a crash loses at most the results not yet committed and never leaves half a log.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import sqlite3
import stat
from pathlib import Path

from drake_est.errors import DataError

SCHEMA_VERSION = 1

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS logs (
    log_id INTEGER PRIMARY KEY,
    robot_id TEXT NOT NULL,
    log_time TEXT NOT NULL,
    path TEXT NOT NULL,
    robot_model TEXT NOT NULL,
    joints TEXT,
    file_sha256 TEXT NOT NULL,
    settings_hash TEXT NOT NULL,
    settings_json TEXT NOT NULL,
    software_version TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    error TEXT,
    n_findings INTEGER,
    nominal_rmse REAL,
    duration_s REAL,
    elapsed_s REAL,
    worker TEXT,
    run_id INTEGER,
    finished_at TEXT NOT NULL,
    UNIQUE (robot_id, log_time, file_sha256, settings_hash)
);
CREATE TABLE IF NOT EXISTS findings (
    log_id INTEGER NOT NULL REFERENCES logs(log_id) ON DELETE CASCADE,
    rank INTEGER NOT NULL,
    effect TEXT NOT NULL,
    joint INTEGER,
    heldout_gain REAL,
    p_value REAL,
    parameters_json TEXT,
    evidence_json TEXT,
    PRIMARY KEY (log_id, rank)
);
CREATE TABLE IF NOT EXISTS parameters (
    log_id INTEGER NOT NULL REFERENCES logs(log_id) ON DELETE CASCADE,
    joint INTEGER NOT NULL,
    name TEXT NOT NULL,
    value REAL NOT NULL,
    PRIMARY KEY (log_id, joint, name)
);
CREATE TABLE IF NOT EXISTS runs (
    run_id INTEGER PRIMARY KEY,
    started_at TEXT NOT NULL,
    finished_at TEXT,
    settings_hash TEXT NOT NULL,
    software_version TEXT NOT NULL,
    scheduler TEXT,
    n_logs INTEGER, n_skipped INTEGER, n_ok INTEGER, n_failed INTEGER, n_unfinished INTEGER
);
CREATE INDEX IF NOT EXISTS logs_robot ON logs (robot_id, log_time);
"""


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


class FleetStore:
    """The SQLite fleet store (see module doc for the schema).  ``FleetStore(path, write=True)``
    creates the file when missing and refuses a read-only file with a one-line :class:`DataError`."""

    def __init__(self, path, write: bool = True):
        self.path = Path(path)
        if not write:
            if not self.path.exists():
                raise DataError(f"store {self.path} does not exist (run 'drake-est fleet diagnose' first)")
            self.con = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True)
            self._check_schema()
            return
        if self.path.exists() and (not os.access(self.path, os.W_OK)
                                   or not self.path.stat().st_mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH)):
            raise DataError(f"store {self.path} is read-only: cannot record results (make it writable or pick "
                            f"another --store)")
        if not self.path.parent.exists():
            raise DataError(f"store folder {self.path.parent} does not exist")
        try:
            self.con = sqlite3.connect(self.path, timeout=30.0)
            self.con.execute("PRAGMA journal_mode=WAL")
            self.con.execute("PRAGMA foreign_keys=ON")
            with self.con:
                self.con.executescript(SCHEMA)
                self.con.execute("INSERT OR IGNORE INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
                self.con.execute("INSERT OR IGNORE INTO meta VALUES ('created_by', 'drake_est.fleet')")
        except sqlite3.OperationalError as err:
            raise DataError(f"store {self.path} cannot be written: {err}") from None
        except sqlite3.DatabaseError as err:
            raise DataError(f"store {self.path} is not a drake_est fleet store (SQLite): {err}") from None
        self._check_schema()

    def _check_schema(self):
        try:
            row = self.con.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
        except sqlite3.DatabaseError as err:
            raise DataError(f"store {self.path} is not a drake_est fleet store: {err}") from None
        if row is None or int(row[0]) != SCHEMA_VERSION:
            raise DataError(f"store {self.path} has schema version {row and row[0]}, expected {SCHEMA_VERSION}")

    def close(self):
        self.con.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------------ runs
    def start_run(self, settings_hash: str, version: str, scheduler: str, n_logs: int, n_skipped: int) -> int:
        with self.con:
            cur = self.con.execute("INSERT INTO runs (started_at, settings_hash, software_version, scheduler, n_logs, "
                                   "n_skipped) VALUES (?, ?, ?, ?, ?, ?)",
                                   (_now(), settings_hash, version, scheduler, n_logs, n_skipped))
        return int(cur.lastrowid)

    def finish_run(self, run_id: int, n_ok: int, n_failed: int, n_unfinished: int):
        with self.con:
            self.con.execute("UPDATE runs SET finished_at=?, n_ok=?, n_failed=?, n_unfinished=? WHERE run_id=?",
                             (_now(), n_ok, n_failed, n_unfinished, run_id))

    # ------------------------------------------------------------------ logs
    def done_keys(self, settings_hash: str) -> set:
        """(robot_id, log_time, file_sha256) of every log already recorded with these settings."""
        rows = self.con.execute("SELECT robot_id, log_time, file_sha256 FROM logs WHERE settings_hash=?",
                                (settings_hash,))
        return {tuple(r) for r in rows}

    def record(self, res: dict, run_id: int | None = None) -> bool:
        """Write one log's result (from :func:`drake_est.fleet.run.diagnose_entry`) in one transaction.
        Returns False when that log and settings were already recorded (nothing is written twice)."""
        e = res["entry"]
        try:
            return self._record(e, res, run_id)
        except sqlite3.OperationalError as err:
            raise DataError(f"store {self.path} cannot be written: {err}") from None

    def _record(self, e, res, run_id):
        with self.con:
            cur = self.con.execute(
                "INSERT OR IGNORE INTO logs (robot_id, log_time, path, robot_model, joints, file_sha256, settings_hash, "
                "settings_json, software_version, status, error, n_findings, nominal_rmse, duration_s, elapsed_s, "
                "worker, run_id, finished_at) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (e["robot_id"], e["time"], e["path"], e["robot_model"], e.get("joints") or "", res["file_sha256"],
                 res["settings_hash"], json.dumps(res["settings"], sort_keys=True), res["software_version"],
                 res["status"], res.get("error"), len(res.get("findings", [])), res.get("nominal_rmse"),
                 res.get("duration_s"), res.get("elapsed_s"), res.get("worker"), run_id, _now()))
            if cur.rowcount == 0:
                return False
            log_id = cur.lastrowid
            for k, f in enumerate(res.get("findings", []), start=1):
                self.con.execute("INSERT INTO findings VALUES (?,?,?,?,?,?,?,?)",
                                 (log_id, k, f["effect"], f.get("joint"), f.get("heldout_gain"), f.get("p_value"),
                                  json.dumps(f.get("parameters", {})), json.dumps(f.get("evidence", {}))))
            for p in res.get("parameters", []):
                self.con.execute("INSERT INTO parameters VALUES (?,?,?,?)", (log_id, p["joint"], p["name"], p["value"]))
        return True

    # ------------------------------------------------------------------ queries (used by trends/report)
    def query(self, sql: str, args=()) -> list:
        return self.con.execute(sql, args).fetchall()

    def counts(self) -> dict:
        rows = dict(self.query("SELECT status, COUNT(*) FROM logs GROUP BY status"))
        return {"logs": int(sum(rows.values())), "ok": int(rows.get("ok", 0)), "failed": int(rows.get("failed", 0)),
                "findings": int(self.query("SELECT COUNT(*) FROM findings")[0][0]),
                "robots": int(self.query("SELECT COUNT(DISTINCT robot_id) FROM logs")[0][0])}
