"""Fleet-scale diagnosis and Monte-Carlo on Dask.

* :func:`run_fleet` -- diagnose every log of a folder tree or manifest in parallel (a
  ``LocalCluster`` of processes, or an existing scheduler), results in an SQLite store
  (:class:`FleetStore`, schema in :mod:`drake_est.fleet.store`); resumable and idempotent.
* :func:`fleet_trends` -- per robot x joint parameter series, change detection (thesis Ch. 7) and
  ranked warnings; :func:`build_report` -- static HTML + JSON report.
* :func:`synth_fleet` -- a synthetic fleet with planted changes (truth kept apart).
* :func:`mc_map` -- a seeded function over parameter sets on Dask, same results for any worker count.

Example::

    from drake_est.fleet import synth_fleet, run_fleet, build_report, FleetStore
    synth_fleet("fleet", robots=6, days=10)
    run_fleet("fleet", "fleet.db", workers=2)
    with FleetStore("fleet.db", write=False) as st:
        rep = build_report(st, "fleet_report")
"""
from drake_est.fleet.mc import child_seed, mc_map
from drake_est.fleet.report import build_report
from drake_est.fleet.run import diagnose_entry, discover, run_fleet
from drake_est.fleet.store import SCHEMA_VERSION, FleetStore
from drake_est.fleet.synth_fleet import synth_fleet
from drake_est.fleet.trends import check_against_truth, detect_change, fleet_trends

__all__ = ["run_fleet", "discover", "diagnose_entry", "FleetStore", "SCHEMA_VERSION", "fleet_trends",
           "detect_change", "check_against_truth", "build_report", "synth_fleet", "mc_map", "child_seed"]
