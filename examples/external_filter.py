"""A filter defined outside the package, benchmarked against the papers' filters.

The fifth-degree spherical-radial cubature rule (Jia, Xin & Cheng 2013, Automatica
49(2)): 2 n^2 + 1 points, the centre with weight 2 / (n + 2), +-sqrt(n + 2) e_i with
(4 - n) / (2 (n + 2)^2) and +-sqrt((n + 2) / 2) (e_i +- e_j), i < j, with 1 / (n + 2)^2.
It integrates every polynomial up to degree five exactly against N(0, I), one degree
beyond the unscented and third-degree cubature rules. Registered as ``cqkf-5`` (nothing
in the package is edited), it runs in paper 002's campaign (the static base, a large
azimuth misalignment) beside the EKF, the UKF and the level-2 sparse-grid GH filter.

Run: python examples/external_filter.py [--episodes N] [--seed S]
(or from the command line: aligngym bench paper002 --filters
external_filter:fifth_degree_cubature, with examples/ on PYTHONPATH)
"""
from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

import aligngym


class FifthDegreeCubature(aligngym.SigmaPointRule):
    """Fifth-degree spherical-radial cubature: 2 n^2 + 1 points (weights above)."""

    name = "cubature-5"

    def __init__(self) -> None:
        # Negative weights for n > 4: the testbed floors the predicted covariance's
        # eigenvalues when they make it indefinite (and counts the repairs).
        self.has_negative_weights = True

    def _points(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        eye = np.eye(n)
        axes = np.sqrt(n + 2.0) * np.vstack([eye, -eye])
        pairs = [s * eye[i] + t * eye[j] for i, j in itertools.combinations(range(n), 2)
                 for s, t in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
        diagonals = np.sqrt((n + 2.0) / 2.0) * np.array(pairs).reshape(-1, n)
        xi = np.vstack([np.zeros((1, n)), axes, diagonals])
        w = np.concatenate([[2.0 / (n + 2.0)],
                            np.full(2 * n, (4.0 - n) / (2.0 * (n + 2.0) ** 2)),
                            np.full(len(diagonals), 1.0 / (n + 2.0) ** 2)])
        return xi, w


def fifth_degree_cubature() -> aligngym.FilterEntry:
    """The entry ``--filters external_filter:fifth_degree_cubature`` imports."""
    return aligngym.FilterEntry(FifthDegreeCubature, aligngym.NoAdaptation,
                                "fifth-degree cubature KF (user-defined)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    aligngym.register_filter("cqkf-5", FifthDegreeCubature,
                             description="fifth-degree cubature KF (user-defined)")
    exp = aligngym.experiment("paper002")
    start = time.perf_counter()
    result = aligngym.run_campaign(exp, episodes=args.episodes, seed=args.seed,
                                   filters=["ekf", "ukf", "sghkf-2", "cqkf-5"])
    print(exp.format_tables(result))
    print(f"{args.episodes} episodes x 4 filters in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
