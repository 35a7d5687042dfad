"""Every integration rule against a seeded Monte Carlo on each paper's own model (issue 42).

For each experiment: one prepared episode (campaign seed 0), its largest start (000, 002
and 004: their large starts; 001 and 003: their only start or the larger), the model of
each variant its filters use, and the first epoch's maps: the transition from the prior
(x0, P0) and the measurement from the predicted state (the UKF's own prediction, so that
every rule sees the same input). Each rule's mean and covariance of y = f(x), x ~ N(m, P),
the map's noise left out, is compared with a Monte Carlo of --draws draws (10^6 by
default, in blocks): the error of each component in units of the Monte Carlo's standard
error (the mean's sqrt(C_ii / N); a covariance entry's std((y_i - m_i)(y_j - m_j)) /
sqrt(N)), the worst component named, and the worst relative error of a variance. Linear
maps are exact under every rule and listed as such. Angle outputs are compared wrapped
around the image of the mean.

Run: python benchmarks/moment_check.py [--draws N] [--papers paper002,...] [--json F]
Writes the table (markdown) to stdout: docs/checks.md's "Rules against Monte Carlo".
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from aligngym.estimators.catalogue import filter_entry
from aligngym.estimators.model import wrap_angle
from aligngym.estimators.rules import (MAX_POINTS, CubatureRule, GaussHermiteRule,
                                       LinearizationRule, ReducedGaussHermiteRule,
                                       SparseGridGaussHermiteRule, UnscentedRule)
from aligngym.scenarios.experiments import experiment, experiment_names

RULES = {
    "ekf (linearisation)": LinearizationRule(),
    "ukf (kappa 0)": UnscentedRule(),
    "ukf-3n (kappa 3 - n)": UnscentedRule(kappa=None),
    "stukf's (n + kappa 1.5)": UnscentedRule(spread=1.5),
    "ckf": CubatureRule(),
    "gh-3 (tensor)": GaussHermiteRule(3),
    "sghkf-2": SparseGridGaussHermiteRule(2),
    "sghkf-3": SparseGridGaussHermiteRule(3),
    "sghkf-4": SparseGridGaussHermiteRule(4),
    "rdghkf (reduced GH 7)": ReducedGaussHermiteRule(7),
}


def monte_carlo(fmap, mean: np.ndarray, cov: np.ndarray, draws: int, seed: int = 0,
                block: int = 100_000) -> dict:
    """Sample mean (d,) and covariance (d, d) of fmap(x), x ~ N(mean (n,), cov (n, n)),
    with their standard errors; angle outputs wrapped around the image of the mean."""
    rng = np.random.default_rng(seed)
    S = np.linalg.cholesky(cov)
    ref = fmap(mean[None, None, :])[0, 0]
    angles = list(fmap.angles)

    def sample(count):
        x = mean + rng.standard_normal((count, mean.size)) @ S.T
        y = fmap(x[None])[0] - ref
        if angles:
            y[:, angles] = wrap_angle(y[:, angles])
        return y

    pilot = sample(min(block, draws)).mean(axis=0)   # centres the sums (less rounding)
    d = pilot.size
    s1, s2, s4 = np.zeros(d), np.zeros((d, d)), np.zeros((d, d))
    done = 0
    while done < draws:
        count = min(block, draws - done)
        e = sample(count) - pilot
        s1 += e.sum(axis=0)
        s2 += e.T @ e
        s4 += (e * e).T @ (e * e)
        done += count
    m1 = s1 / draws
    C = s2 / draws - np.outer(m1, m1)
    var_outer = s4 / draws - (s2 / draws) ** 2
    mean_y = ref + pilot + m1
    if angles:
        mean_y[angles] = wrap_angle(mean_y[angles])
    return {"mean": mean_y, "cov": C, "se_mean": np.sqrt(np.diag(C) / draws),
            "se_cov": np.sqrt(np.maximum(var_outer, 0.0) / draws)}


def compare(rule, fmap, mean, cov, mc: dict) -> dict:
    """The rule's errors against the Monte Carlo, or {"skipped": why} where it does not
    apply to the map."""
    try:
        y, C, _ = rule.moments(fmap, mean[None], cov[None])
    except ValueError as exc:          # the rule does not apply to this map
        return {"skipped": str(exc).split(";")[0]}
    dm = y[0] - mc["mean"]
    if fmap.angles:
        dm[list(fmap.angles)] = wrap_angle(dm[list(fmap.angles)])
    z_mean = np.abs(dm) / np.maximum(mc["se_mean"], 1e-300)
    z_cov = np.abs(C[0] - mc["cov"]) / np.maximum(mc["se_cov"], 1e-300)
    diag = np.diag(mc["cov"])
    rel_var = np.abs(np.diag(C[0]) - diag) / np.maximum(diag, 1e-300)
    return {"mean_se": float(z_mean.max()), "mean_worst": int(z_mean.argmax()),
            "cov_se": float(z_cov.max()),
            "cov_worst": [int(i) for i in np.unravel_index(z_cov.argmax(), z_cov.shape)],
            "var_rel": float(rel_var.max()), "var_worst": int(rel_var.argmax())}


def maps_of(name: str, seed: int = 0):
    """[(label, map, mean (n,), cov (n, n))] of the experiment's first epoch, for each
    model variant its default filters use, from its largest start."""
    exp = experiment(name)
    episode = exp.prepare_episode(seed)
    starts = exp.start_errors([episode])
    start_name = max(starts, key=lambda s: float(np.max(np.abs(starts[s]))))
    start = np.broadcast_to(np.asarray(starts[start_name], dtype=float), (1, 3))
    variants = sorted({filter_entry(f).model for f in exp.default_filters})
    out = []
    for variant in variants:
        model = exp.model([episode], start, variant)
        x0, P0 = model.initial()
        f = model.transition(0)
        out.append((f"{name} {variant or 'default'} transition ({start_name} start)", f,
                    x0[0], P0[0]))
        # The measurement at the UKF's prediction (the same input for every rule).
        if f.linear:
            xp, Pp, _ = LinearizationRule().moments(f, x0, P0)
        else:
            xp, Pp, _ = UnscentedRule().moments(f, x0, P0)
        Pp = Pp + f.noise
        h = model.observation(0)
        out.append((f"{name} {variant or 'default'} measurement", h, xp[0],
                    0.5 * (Pp[0] + Pp[0].T)))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draws", type=int, default=1_000_000)
    parser.add_argument("--papers", default=",".join(experiment_names()))
    parser.add_argument("--json", help="write the numbers to this file")
    args = parser.parse_args(argv)
    results = []
    print("| model, map | n -> d | rule | mean error (MC SE) | covariance error (MC SE) "
          "| worst variance error |")
    print("|---|---|---|---|---|---|")
    for name in args.papers.split(","):
        for label, fmap, mean, cov in maps_of(name):
            n, d = mean.size, (fmap.matrix.shape[1] if fmap.linear else
                               fmap(mean[None, None])[0, 0].size)
            if fmap.linear:
                print(f"| {label} | {n} -> {d} | every rule | linear: exact | | |")
                results.append({"map": label, "linear": True})
                continue
            start = time.perf_counter()
            mc = monte_carlo(fmap, mean, cov, args.draws)
            seconds = time.perf_counter() - start
            for rule_name, rule in RULES.items():
                if rule.point_count(n) > MAX_POINTS:
                    continue
                row = compare(rule, fmap, mean, cov, mc)
                results.append({"map": label, "rule": rule_name, **row,
                                "mc_seconds": seconds})
                if "skipped" in row:
                    continue
                print(f"| {label} | {n} -> {d} | {rule_name} | {row['mean_se']:.1f} "
                      f"(y{row['mean_worst']}) | {row['cov_se']:.1f} "
                      f"(y{row['cov_worst'][0]},{row['cov_worst'][1]}) | "
                      f"{100 * row['var_rel']:.2f} % (y{row['var_worst']}) |")
            sys.stdout.flush()
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"draws": args.draws, "results": results}, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
