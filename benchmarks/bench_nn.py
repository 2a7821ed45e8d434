"""Benchmark of neural-dynamics training (thesis Ch. 8): one training epoch on the pendulum-on-a-cart task
(two 200-step trajectories = 398 training samples, 3 hidden layers of 30, g + x form, mini-batches of 50,
Adam), with the Jacprop term (8.9) and its exact gradient (double backprop of Algorithm 4) and without it
(plain prediction-error training, same code path).  For reference the plain epoch is also timed with
Drake's ``MultilayerPerceptron.BackpropagationMeanSquaredError`` doing the forward/backward pass (same
batches, Adam on its parameter vector).

An epoch is ``drake_est.identification.nn.train_epoch`` (batching + gradients + Adam updates); times are the
best of ``--repeat`` blocks of ``--epochs`` epochs each, single-threaded BLAS, one process (one core).
Usage: python benchmarks/bench_nn.py [--repeat 5] [--epochs 20] [--json FILE]
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np


def _setup(seed=0):
    from drake_est.identification import nn
    from drake_est.identification.nn_tasks import simulate_cartpole

    rng = np.random.default_rng(seed)
    trajs = [simulate_cartpole(rng, T=200) for _ in range(2)]
    X, U = nn._as_trajectories([t[0] for t in trajs], [t[1] for t in trajs])
    data = nn._stack(X, U)
    N = np.hstack([np.eye(4), np.zeros((4, 1))])
    scal = nn._Scaling.from_data(data, N, True)
    data = scal.apply(data, N)
    params = nn.init_params([5, 30, 30, 30, 4], np.random.default_rng(seed), 0.1)
    return nn, data, params


def _time_epochs(nn, data, params, jacprop, epochs, repeat, batch_size):
    best = np.inf
    rng = np.random.default_rng(1)
    for _ in range(repeat):
        adam = nn.Adam(params, 1e-3)
        p = params
        orders = [rng.permutation(data.Z.shape[0]) for _ in range(epochs)]
        t = time.perf_counter()
        for o in orders:
            p, _, bad = nn.train_epoch(p, data, o, batch_size, adam, jacprop=jacprop)
        best = min(best, (time.perf_counter() - t) / epochs)
        assert not bad
    return best * 1e3


def _time_drake_plain(nn, data, params, epochs, repeat, batch_size):
    from pydrake.systems.primitives import MultilayerPerceptron, PerceptronActivationType as Act

    mlp = MultilayerPerceptron([5, 30, 30, 30, 4], [Act.kTanh] * 3 + [Act.kIdentity])
    ctx = mlp.CreateDefaultContext()
    for i, (W, b) in enumerate(params):
        mlp.SetWeights(ctx, i, W)
        mlp.SetBiases(ctx, i, b)
    theta0 = np.array(mlp.GetParameters(ctx))
    Zt, Yt = np.asfortranarray(data.Z.T), np.asfortranarray(data.Y.T)
    rng = np.random.default_rng(1)
    best = np.inf
    for _ in range(repeat):
        theta = theta0.copy()
        m, v, step = np.zeros_like(theta), np.zeros_like(theta), 0
        g = np.zeros_like(theta)
        orders = [rng.permutation(Zt.shape[1]) for _ in range(epochs)]
        t = time.perf_counter()
        for o in orders:
            for s0 in range(0, o.size, batch_size):
                idx = np.sort(o[s0:s0 + batch_size])
                mlp.SetParameters(ctx, theta)
                mlp.BackpropagationMeanSquaredError(ctx, np.asfortranarray(Zt[:, idx]),
                                                    np.asfortranarray(Yt[:, idx]), g)
                step += 1
                m = 0.9 * m + 0.1 * g
                v = 0.999 * v + 0.001 * g * g
                theta = theta - 1e-3 * (m / (1 - 0.9 ** step)) / (np.sqrt(v / (1 - 0.999 ** step)) + 1e-8)
        best = min(best, (time.perf_counter() - t) / epochs)
    return best * 1e3


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--batch-size", type=int, default=50)
    ap.add_argument("--json", default=None, help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    nn, data, params = _setup()
    res = {"task": "pendulum on a cart, 3 x 30 tanh, g + x", "n_samples": int(data.Z.shape[0]),
           "batch_size": args.batch_size, "epochs_per_block": args.epochs, "repeat": args.repeat,
           "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}
    res["epoch_ms_plain"] = _time_epochs(nn, data, params, 0.0, args.epochs, args.repeat, args.batch_size)
    res["epoch_ms_jacprop"] = _time_epochs(nn, data, params, 1.0, args.epochs, args.repeat, args.batch_size)
    res["epoch_ms_jacprop_full_batch"] = _time_epochs(nn, data, params, 1.0, args.epochs, args.repeat,
                                                      data.Z.shape[0])
    try:
        res["epoch_ms_plain_drake_mlp"] = _time_drake_plain(nn, data, params, args.epochs, args.repeat,
                                                            args.batch_size)
    except ImportError:
        res["epoch_ms_plain_drake_mlp"] = None
    res["jacprop_over_plain"] = res["epoch_ms_jacprop"] / res["epoch_ms_plain"]
    for k, v in res.items():
        print(f"{k:32s} {v:.3f}" if isinstance(v, float) else f"{k:32s} {v}")
    if args.json:
        from drake_est.jsonutil import dump_json
        dump_json(res, args.json)
    return res


if __name__ == "__main__":
    main()
