"""Meshcat views of seam tracking (thesis Ch. 14): the self-contained replay seam.html animates the robot, the
laser stripes and the particle cloud over time; the live Meshcat of the Diagram updates them during the run."""
import base64
import json
import re
import subprocess

import numpy as np
import pytest

from drake_est.seam import viz
from drake_est.seam.analysis import filter_config_for, write_meshcat_html
from drake_est.seam.seam import thesis_seam
from drake_est.seam.simulate import ScenarioConfig, make_scenario, run_loop


@pytest.fixture(scope="module")
def short_run():
    """A coarse, fast run: 200 mm at 1 m/s with a 10 ms period (~25 steps), two stripes, 40 particles."""
    scn = make_scenario(thesis_seam("xy", n_points=81), ScenarioConfig(speed=1.0, dt=1e-2), seed=0)
    cfg = filter_config_for(scn, 2, 40)
    res = run_loop(scn, cfg, closed_loop=True, seed=0, particle_every=2)
    return scn, cfg, res


def _commands(html: str) -> list:
    """The Meshcat commands embedded in a StaticHtml page (msgpack, base64; msgpack comes with dask[distributed])."""
    import msgpack
    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)', html)
    return [msgpack.unpackb(base64.b64decode(b), raw=False, strict_map_key=False,
                            ext_hook=lambda code, data: msgpack.ExtType(code, data)) for b in blobs]


def _tracks(html: str) -> dict:
    """{scene path: {track name: [(frame, value), ...]}} of the page's animation."""
    anims = [c for c in _commands(html) if c.get("type") == "set_animation"]
    assert len(anims) == 1
    out = {}
    for a in anims[0]["animations"]:
        for tr in a["clip"]["tracks"]:
            out.setdefault(a["path"], {})[tr["name"]] = [(k["time"], k["value"]) for k in tr["keys"]]
    return out


def _visible_at(keys, frame):
    """Value of a discrete boolean track at ``frame`` (last key at or before it; the first key before all)."""
    val = keys[0][1]
    for f, v in keys:
        if f <= frame:
            val = v
    return val


def test_replay_animates_lasers_particles_and_robot(short_run, tmp_path):
    from pydrake.geometry import Meshcat
    scn, cfg, res = short_run
    meshcat = Meshcat()
    path = write_meshcat_html(scn, res, cfg, tmp_path / "seam.html", meshcat=meshcat, frames=20, clouds=6)
    tracks = _tracks(path.read_text())
    base = f"/drake/{viz.PREFIX}"
    for p in ("seam", "laser/0", "laser/1", "tool", "estimate", "particles", "particles/0"):
        assert meshcat.HasPath(f"{viz.PREFIX}/{p}"), p
    # the laser stripes and the particles' frame move: their positions change over the frames
    for p in (f"{base}/laser/0", f"{base}/laser/1", f"{base}/particles", f"{base}/tool", f"{base}/estimate"):
        pos = np.array([v for _, v in tracks[p][".position"]], float)
        assert pos.shape[0] >= 10, p
        assert np.ptp(pos, axis=0).max() > 0.1, p          # the tool travels 200 mm
    # the laser stripe sits 40 / 80 mm ahead of the true tool at every frame (sensor_mount)
    tool = dict(tracks[f"{base}/tool"][".position"])
    for s, d in enumerate(cfg.sensor_distances):
        las = dict(tracks[f"{base}/laser/{s}"][".position"])
        gaps = [np.linalg.norm(np.subtract(las[f], tool[f])) for f in las if f in tool]
        assert np.allclose(gaps, d, atol=1e-6)
    # robot links are animated too
    assert sum(p.startswith("/drake/visualizer") for p in tracks) >= 6
    # particle snapshots: exactly one visible at every animation frame, and every snapshot shown at some frame
    snaps = sorted((p for p in tracks if re.fullmatch(rf"{base}/particles/\d+", p)),
                   key=lambda p: int(p.rsplit("/", 1)[1]))
    assert 2 <= len(snaps) <= 6
    frames = sorted({f for _, f_v in tracks[f"{base}/tool"].items() for f, _ in f_v})
    shown = np.array([[_visible_at(tracks[p][".visible"], f) for p in snaps] for f in frames])
    assert (shown.sum(1) == 1).all()
    assert shown.any(0).all()
    # ... in time order
    assert (np.diff(shown.argmax(1)) >= 0).all()


def test_frame_poses_put_the_hit_on_the_seam(short_run):
    scn, cfg, res = short_run
    k = 5
    X_nom = scn.robot.forward_kinematics(res.q_cmd[k]).GetAsMatrix4() @ scn.X_FT
    P = viz.frame_poses(res.X_true[k], X_nom, res.X_est[k], cfg.sensor_distances, scn.seam.points,
                        scn.seam.normals)
    for s, hit in enumerate(P["hit"]):
        assert hit is not None
        # in the laser plane of stripe s, and on the seam polyline (within its sampling)
        X_WS = P["laser"][s]
        assert abs((hit - X_WS[:3, 3]) @ X_WS[:3, 2]) < 1e-9
        assert np.min(np.linalg.norm(scn.seam.points - hit, axis=1)) < 3e-3


def test_write_meshcat_html_rejects_too_few_frames(short_run, tmp_path):
    from drake_est.errors import DataError
    scn, cfg, res = short_run
    with pytest.raises(DataError, match="frames"):
        write_meshcat_html(scn, res, cfg, tmp_path / "x.html", frames=1)


@pytest.mark.slow
def test_replay_renders_in_a_real_browser(short_run, tmp_path, require_browser):
    """seam.html in headless Chromium: no page errors, and the picture shows the red seam and green stripes."""
    import matplotlib.image as mpimg
    scn, cfg, res = short_run
    path = write_meshcat_html(scn, res, cfg, tmp_path / "seam.html")
    png = tmp_path / "seam.png"
    p = subprocess.run([str(require_browser), str(path), str(png), "--wait-ms", "3000"], capture_output=True, text=True,
                       timeout=300)
    info = json.loads(p.stdout.strip().splitlines()[-1])
    assert p.returncode == 0 and info["page_errors"] == [], p.stdout + p.stderr
    img = (mpimg.imread(png)[..., :3] * 255).astype(int)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50            # not blank
    assert ((r > 170) & (g < 90) & (abs(g - b) < 20)).sum() > 50      # the seam line (red, not the orange arm)
    assert ((g > 150) & (r < 120) & (b < 120)).sum() > 5              # laser stripes / hits


def _packed_transform(meshcat, path):
    """The 4x4 transform last sent for ``path`` (Meshcat's packed set_transform message)."""
    import msgpack
    msg = msgpack.unpackb(meshcat._GetPackedTransform(path), raw=False)
    return np.array(msg["matrix"], float).reshape(4, 4).T          # column-major in the message


def test_live_meshcat_in_the_diagram_draws_and_does_not_change_the_run():
    from pydrake.geometry import Meshcat
    from pydrake.systems.analysis import Simulator
    from drake_est.seam.filter import sensor_mount
    from drake_est.systems.seam import MakeSeamTrackingDiagram
    scn = make_scenario(thesis_seam("xy", n_points=81), ScenarioConfig(speed=1.0, dt=1e-2), seed=0)
    cfg = filter_config_for(scn, 2, 40)
    t_end = (scn.T - 1) * scn.config.dt
    logs = []
    meshcat = Meshcat()
    for m in (None, meshcat):
        diagram, h = MakeSeamTrackingDiagram(scn, cfg, seed=0, meshcat=m, meshcat_period=0.05)
        sim = Simulator(diagram)
        sim.AdvanceTo(t_end)
        ctx = sim.get_context()
        logs.append((h["log_est"].FindLog(ctx).data().copy(), h["log_pose"].FindLog(ctx).data().copy()))
        if m is None:
            assert h["meshcat_overlay"] is None and h["meshcat_visualizer"] is None
    # the live view only observes: the run is bit-identical with and without it
    np.testing.assert_array_equal(logs[0][0], logs[1][0])
    np.testing.assert_array_equal(logs[0][1], logs[1][1])
    for p in ("seam", "laser/0", "laser/1", "laser_hit/0", "tool", "estimate", "particles", "particles/live"):
        assert meshcat.HasPath(f"{viz.PREFIX}/{p}"), p
    assert meshcat.HasPath("visualizer")
    # the last publish (t = 0.05 k <= t_end) put the laser stripe at the true tool pose of that time times T_S
    t_pub = np.floor(t_end / 0.05 + 1e-9) * 0.05
    k = int(round(t_pub / scn.config.dt))
    X_true = logs[1][1][:, k].reshape(4, 4)
    X_las = _packed_transform(meshcat, f"{viz.PREFIX}/laser/0")
    np.testing.assert_allclose(X_las, X_true @ sensor_mount(cfg.sensor_distances[0]), atol=1e-9)


def test_cli_bad_realtime_rate_exits_2(tmp_path):
    import sys
    r = subprocess.run([sys.executable, "-m", "drake_est", "track", "--seam", "xy", "--realtime-rate", "0",
                        "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--realtime-rate" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
