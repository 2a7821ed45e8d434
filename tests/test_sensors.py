"""Drake LeafSystems that simulate calibration data on the IRB 140: ForceTorqueSensor, LaserStripeScanner."""
import numpy as np
import pytest

from drake_est.calibration import (
    calibrate_ft, calibrate_laser, exp_so3, make_pose, perturb_transform, rotation_error, transform_error,
)
from drake_est.errors import DataError

R_FS = np.column_stack([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).astype(float)  # laser looks along the tool z axis
X_FS = make_pose(R_FS @ exp_so3([0.05, -0.03, 0.1]), [0.01, 0.04, 0.08])
PLANES = np.array([[1, 0, 0, 0.9], [0, 0, 1, 0.15], [0, 1, 0, -0.5]])  # wall, floor, side wall


def _diagram(**kw):
    from drake_est.robots import add_irb140
    from drake_est.systems.sensors import ForceTorqueSensor, LaserStripeScanner

    builder, plant, _, _ = add_irb140()
    sc = builder.AddSystem(LaserStripeScanner(plant, X_FS, PLANES, n_rays=48, noise=0.5e-3, max_range=1.2,
                                              seam=([0.9, -0.2, 0.0], [0.0, 0.0, 1.0])))
    ft = builder.AddSystem(ForceTorqueSensor(plant, X_FS, mass=1.2, com=[0.0, 0.01, 0.06], force_bias=[1, 0, -0.5],
                                             torque_bias=[0.02, 0, 0], noise_force=0.02, noise_torque=0.001))
    builder.Connect(plant.get_state_output_port(), sc.get_input_port(0))
    builder.Connect(plant.get_state_output_port(), ft.get_input_port(0))
    return builder.Build(), plant, sc, ft


def _configs(n, seed=0):
    rng = np.random.default_rng(seed)
    lo = np.array([-1.2, -0.3, -0.6, -1.5, -1.6, -3.0])
    hi = -lo
    hi[1] = 0.6
    return rng.uniform(lo, hi, (n, 6))


def test_ports_and_static_wrench_physics():
    d, plant, sc, ft = _diagram()
    assert ft.get_input_port(0).get_name() == "robot_state"
    assert [ft.get_output_port(i).get_name() for i in range(ft.num_output_ports())] == ["wrench"]
    names = [sc.get_output_port(i).get_name() for i in range(sc.num_output_ports())]
    assert names == ["points", "plane_labels", "seam_point"]
    ctx = d.CreateDefaultContext()
    w1 = ft.GetOutputPort("wrench").Eval(ft.GetMyContextFromRoot(ctx)).copy()
    w2 = ft.GetOutputPort("wrench").Eval(ft.GetMyContextFromRoot(ctx)).copy()
    assert np.array_equal(w1, w2)  # noise is a function of (seed, sample), not of evaluation count
    # the force magnitude is m g (+ offset and noise)
    assert abs(np.linalg.norm(w1[:3] - [1, 0, -0.5]) - 1.2 * 9.81) < 0.1


def test_calibrations_recover_the_simulated_mounts():
    from drake_est.systems.sensors import collect_laser_scans, collect_wrenches

    d, plant, sc, ft = _diagram()
    Q = _configs(80)
    P, pts, idx, lab = collect_laser_scans(d, sc, plant, Q)
    assert set(np.unique(lab)) == {0, 1, 2}
    # the points lie on the planes they are labelled with (noise 0.5 mm)
    from drake_est.calibration import transform_points

    Pw = transform_points(P, X_FS, pts, idx)
    dist = np.einsum("ni,ni->n", Pw, PLANES[lab, :3]) - PLANES[lab, 3]
    assert np.sqrt(np.mean(dist**2)) < 1e-3
    rng = np.random.default_rng(1)
    res = calibrate_laser(P, pts, idx, labels=lab, T0=perturb_transform(X_FS, rng, 0.2, 30.0))
    et, er = transform_error(res.T, X_FS)
    assert et < 0.5e-3 and np.degrees(er) < 0.1
    P2, W = collect_wrenches(d, ft, plant, Q[:30])
    cal = calibrate_ft(P2, W)
    assert rotation_error(cal.R, X_FS[:3, :3].T) < 3e-3
    assert abs(cal.mass - 1.2) < 0.012 and np.allclose(cal.com, [0.0, 0.01, 0.06], atol=2e-3)


def test_seam_point_lies_on_the_seam():
    d, plant, sc, ft = _diagram()
    ctx = d.CreateDefaultContext()
    found = 0
    for q in _configs(60, seed=3):
        plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), q)
        sctx = sc.GetMyContextFromRoot(ctx)
        s = sc.GetOutputPort("seam_point").Eval(sctx)
        if np.all(np.isfinite(s)):
            found += 1
            T = sc.sensor_pose(sctx)
            pw = T[:3, :3] @ s + T[:3, 3]
            assert abs(pw[0] - 0.9) < 3e-3 and abs(pw[1] + 0.2) < 3e-3  # on the line x = 0.9, y = -0.2
            assert abs(s[2]) == 0.0  # in the laser plane
    assert found >= 1


def test_bad_sensor_arguments():
    from drake_est.robots import add_irb140
    from drake_est.systems.sensors import ForceTorqueSensor, LaserStripeScanner

    _, plant, _, _ = add_irb140()
    with pytest.raises(DataError, match="planes"):
        LaserStripeScanner(plant, X_FS, np.zeros((2, 3)))
    with pytest.raises(DataError, match="mass"):
        ForceTorqueSensor(plant, X_FS, mass=-1.0)
    with pytest.raises(DataError, match="frame"):
        ForceTorqueSensor(plant, X_FS, flange_frame="nope")
