"""Mutation testing of the numerical core against the fast tests aimed at it (issue 41).

Each target module is mutated by cosmic-ray (one small change at a time: an operator, a
comparison, a number, a boolean, a loop) and the fast tests named for it run against
each mutant; a mutant the tests pass is a survivor. Writes, under --out:
``NAME.toml`` and ``NAME.sqlite`` (cosmic-ray's config and session, resumable: a second
run continues where the first stopped), ``report.json`` and ``report.md`` (per target:
mutants, killed, survivors with their diff, the equivalent ones with their reason) and
``checks.md`` (the table and the equivalent survivors by reason: docs/checks.md's
section).

Why cosmic-ray: it mutates the checkout's files in place and restores them, so the
tests import the mutant through the editable install of this checkout (the package-dir
layout maps ``aligngym.estimators`` to ``estimators/``); mutmut 3 runs the tests on a
copy under ``mutants/`` that the installed package would not import.

Run it in a checkout of its own (the files are mutated while it runs), installed
editable (``pip install -e '.[test]' cosmic-ray``):

    git clone . /tmp/mutation && cd /tmp/mutation && python benchmarks/mutation.py

Excluded operators (``EXCLUDED_OPERATORS``): arithmetic replaced by a bitwise or shift
operator. On the float arrays of this code they raise TypeError at the first call:
every test fails on them, so they would only inflate the kill rate.
"""
from __future__ import annotations

import argparse
import ast
import json
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

FAST = "-x -q -n 0 -p no:cacheprovider"
ADAPTATION_TESTS = ("tests/test_adaptation.py tests/test_adaptation_001.py "
                    "tests/test_adaptation_mutants.py")
"""The fast tests of the adaptation policies (protocol, fading factors, robust)."""
TARGETS: dict[str, tuple[str, tuple[str, ...] | None]] = {
    # module: (the fast tests aimed at it, the functions mutated (None: all))
    "estimators/linalg.py": ("tests/test_linalg.py tests/test_filters.py", None),
    "estimators/metrics.py": ("tests/test_metrics.py tests/test_reliability.py", None),
    "estimators/filters.py": ("tests/test_filters.py tests/test_filter_guards.py "
                              "tests/test_linear_exactness.py tests/test_filter_mutants.py",
                              None),
    "scenarios/campaign/experiment.py": ("tests/test_nees_maps.py", ("nees", "nees_dof")),
    "scenarios/experiments/paper000.py": ("tests/test_nees_maps.py", ("state_errors",)),
    "scenarios/experiments/paper001.py": ("tests/test_nees_maps.py", ("state_errors",)),
    "scenarios/experiments/paper002.py": ("tests/test_nees_maps.py", ("state_errors",)),
    "scenarios/experiments/paper003.py": ("tests/test_nees_maps.py",
                                          ("sensor_frame_errors", "hull_frame_floor",
                                           "about_floor_errors", "truth_map")),
    "scenarios/experiments/paper004.py": ("tests/test_nees_maps.py", ("state_errors",)),
    "estimators/rules.py": ("tests/test_rules.py tests/test_rules_definitions.py "
                            "tests/test_linear_exactness.py", None),
    "estimators/strapdown.py": ("tests/test_strapdown_units.py tests/test_strapdown.py -k "
                                "'not fidelity'", None),
    "estimators/adaptation.py": (ADAPTATION_TESTS, None),
    "estimators/fading_factors.py": (ADAPTATION_TESTS, None),
    "estimators/robust_adaptive.py": (ADAPTATION_TESTS, None),
    "sensors/imu.py": ("tests/test_imu.py tests/test_imu_units.py", None),
    "sensors/encoder.py": ("tests/test_imu.py tests/test_encoder.py", None),
}
EXCLUDED_OPERATORS = [r"core/ReplaceBinaryOperator_(Add|Sub|Mul|Div|FloorDiv|Mod|Pow)_"
                      r"(BitOr|BitAnd|BitXor|LShift|RShift)$"]
SQUARE = ("A and P are (B, n, n) batches of square matrices: shape[-1], shape[1], "
          "shape[-2] and shape[+1] are all n")
EQUIVALENT: dict[str, str] = {
    "estimators/linalg.py:12: return A if keep.all() else np.where(keep, A, "
    "np.eye(A.shape[+1]))": SQUARE,
    "estimators/linalg.py:12: return A if keep.all() else np.where(keep, A, "
    "np.eye(A.shape[~1]))": SQUARE,
    "estimators/linalg.py:12: return A if keep.all() else np.where(keep, A, "
    "np.eye(A.shape[1]))": SQUARE,
    "estimators/linalg.py:12: return A if keep.all() else np.where(keep, A, "
    "np.eye(A.shape[- 2]))": SQUARE,
    "estimators/linalg.py:33: floor = relative * np.maximum(np.trace(P, axis1=-2, "
    "axis2=-1), 0.0) / P.shape[+1]": SQUARE,
    "estimators/linalg.py:33: floor = relative * np.maximum(np.trace(P, axis1=-2, "
    "axis2=-1), 0.0) / P.shape[~1]": SQUARE,
    "estimators/linalg.py:33: floor = relative * np.maximum(np.trace(P, axis1=-2, "
    "axis2=-1), 0.0) / P.shape[1]": SQUARE,
    "estimators/linalg.py:33: floor = relative * np.maximum(np.trace(P, axis1=-2, "
    "axis2=-1), 0.0) / P.shape[- 2]": SQUARE,
    "estimators/linalg.py:33: floor = relative * np.maximum(np.trace(P, axis1=-2, "
    "axis2=-1), -1.0) / P.shape[-1]": "a trace in (-1, 0) makes the floor negative, "
    "and the next line raises any floor below 1e-300 to 1e-300, as for a trace of 0",
}
"""Survivors shown equivalent, by ``module:line: the mutated line``, with the reason:
the mutant computes the same numbers as the original for every input the code can
receive."""

_M = "estimators/metrics.py:"
_TWO_D = "final_error, final_sigma and the error are (B, 3): axis 1 is axis -1"
_BOOL_ADD = "numpy adds boolean arrays as a logical or (and multiplies them as an and)"
EQUIVALENT.update({
    _M + "24: return (d - np.pi) % (2 * np.pi) - np.pi": "(d - pi) mod 2 pi = (d + pi) mod 2 pi",
    _M + '41: return np.einsum("...i,...i->...", error, np.linalg.solve(P, error[..., '
         'None])[..., -1])': "the solve's last axis has length 1: index -1 is index 0",
    _M + "50: @dataclass(frozen=False)": "no code assigns to a rule's fields; frozen only "
                                         "refuses an assignment",
    _M + "78: broken = ~np.all(np.isfinite(error), axis=-1) + ~np.all(np.isfinite("
         "final_sigma),": _BOOL_ADD,
    _M + "81: wrong = np.any((error > self.ratio * 3.0 * final_sigma) * (error > "
         "self.floor),": _BOOL_ADD,
    **{_M + f"{line}: {text.format(a)}": _TWO_D for a in ("+1", "1") for line, text in (
        (78, "broken = ~np.all(np.isfinite(error), axis={}) | ~np.all(np.isfinite("
             "final_sigma),"),
        (79, "axis={})"), (80, "lost = np.any(error > self.lost_bound, axis={})"),
        (82, "axis={})"), (83, "wide = np.any(final_sigma > self.sigma_bound, axis={})"),
        (84, "outside = np.any(error > band, axis={})"))},
})


_F = "estimators/filters.py:"
# Keyed by the lines of filters.py after the update was split into helpers and the
# catalogue moved to estimators/catalogue.py (2026-12-06; run of 521 mutants). The
# filters.py survivors that are not listed here or in EQUIVALENT_PATTERNS (NIS over the
# valid components, NaN without one or not live; a missing component's R not read and
# its unit row and column of S; unadapted_valid; the harmless point of a diverged
# episode) are killed by tests/test_filter_mutants.py.
_BOOL_MUL = ("numpy multiplies boolean arrays as a logical and (every operand here is a "
             "boolean mask: isfinite, positive_definite, the live flags, valid, a "
             "policy's rejected = w == 0)")
_SQ = "I - KH is a (B, n, n) batch of square matrices: every one of its last two axes has length n"
_AX = "x, x_new and valid are (B, n) and (B, m) arrays: axis 1 is axis -1"
_MISSING = ("the measurement's missing components: _innovation zeroes them (np.where(valid, "
            "z - z_hat, 0)), whatever z holds there")
_UNSOLVED = ("the gain of an episode whose S is singular, which is flagged in the line above "
             "and then left out of the update of x and P")
EQUIVALENT.update({
    **{_F + key: _BOOL_MUL for key in (
        "41: for b in np.flatnonzero(mask * ~self.diverged):",
        "89: used = live[:, None] * valid",
        "91: S = identity_where_not(used[:, :, None] * used[:, None, :], S)",
        "95: return np.where((dof > 0) * live, nis, np.nan), dof",
        "173: valid = observation.valid() * self.live[:, None]",
        "195: finite = np.all(np.isfinite(P_pred), axis=(-2, -1)) * np.all(np.isfinite("
        "self.x), -1)",
        "223: valid = valid * ~adjustment.rejected",
        "246: cross_valid = valid[:, :, None] * valid[:, None, :]",
        "287: P_ok = positive_definite(P_new) * np.all(np.isfinite(x_new), axis=-1)",
        "302: bad = ~ok * live",
        '306: self.health.flag(bad * ~finite, t, "predicted covariance NaN/inf")',
        "307: fix = bad * finite",
        "312: still = ~positive_definite(repaired) * fix")},
    **{_F + f"282: I_KH[..., np.arange(I_KH.shape[{a}]), np.arange(I_KH.shape[{b}])] += 1.0":
       _SQ for i in ("+1", "~1", "1", "- 2") for a, b in ((i, "-1"), ("-1", i))},
    **{_F + f"{line}: {text.format(i)}": _AX for i in ("+1", "1") for line, text in (
        (94, "dof = valid.sum({})"),
        (195, "finite = np.all(np.isfinite(P_pred), axis=(-2, -1)) & np.all(np.isfinite("
              "self.x), {})"),
        (221, "silent = ~valid.any({})[:, None, None]  # no measurement: no adaptation either"),
        (287, "P_ok = positive_definite(P_new) & np.all(np.isfinite(x_new), axis={})"))},
    **{_F + f"174: z = np.where(valid, observation.z, {v})": _MISSING for v in ("1.0", "-1.0")},
    **{_F + f"269: S_inv_HP = np.where(solved[:, None, None], S_inv_HP, {v})": _UNSOLVED
       for v in ("1.0", "-1.0")},
    _F + "91: S = identity_where_not(used[:, :, None] << used[:, None, :], S)":
        "bool << bool is nonzero where the left operand is True: the unused components' "
        "rows of S become identity rows while the used rows keep their (used, unused) "
        "entries; with e zero where unused the solve gives 0 there and S_uu^-1 e_u on "
        "the used ones, the same NIS to rounding (within 1e-13 relative over 3000 "
        "random batches with junk, zero and NaN in the unused entries)",
    _F + "95: return np.where((dof != 0) & live, nis, np.nan), dof":
        "dof counts valid components: never negative, so != 0 is > 0",
    _F + '93: nis = np.einsum("bi,bi->b", e, solve_each(S, e[..., None])[0][..., -1])':
        "the solve of (B, m, 1) has a last axis of length 1: index -1 is index 0",
    _F + "312: still = ~positive_definite(repaired) ** fix":
        "~(a ** b) is the integer -1 exactly where a is False and b True, -2 elsewhere; "
        "FilterHealth.flag ands it with a boolean array (-1 & 1 = 1, -2 & 1 = 0): the "
        "original mask",
    _F + "208: H = np.swapaxes(np.linalg.pinv(P_pred, hermitian=False) @ P_xz, -1, -2)":
        "P_pred is symmetric (symmetric() above; a repaired one to rounding): its SVD is "
        "its eigendecomposition up to signs, so both give the same pseudo-inverse in exact "
        "arithmetic, with the same cut-off (|eigenvalues| are its singular values); in "
        "floating point they differ by rounding",
    _F + "45: @dataclass(frozen=False)": "no code assigns to an UpdateReport's fields; "
        "frozen only refuses an assignment (and hashing one fails either way: its fields "
        "are arrays)",
})

_R = "estimators/rules.py:"
_ONE = "fmap of the mean alone is one point: index -1 is index 0"
_TINY = ("points below 1e-14 are zeroed for the sparse grid's merging of equal points, "
         "whose keys are rounded to 12 digits anyway (-0.0 and 1e-16 merge with 0.0)")
_MEAN_2D = "mean is (B, n): axis 1 is axis -1"
EQUIVALENT.update({
    _R + "28: MAX_POINTS = 200001": "no tensor grid m^n (m <= 9) has 200001 points",
    _R + "82: y = fmap(mean[:, None, :])[:, -1]": _ONE,
    _R + "131: reference = fmap(mean[:, None, :])[:, -1]": _ONE,
    _R + "88: ": "the cache of a pure function removed: the same values, computed again",
    _R + "267: ": "the cache of a pure function removed: the same values, computed again",
    _R + "267: @lru_cache(maxsize= 31)": "the size of a pure function's cache",
    _R + "267: @lru_cache(maxsize= 33)": "the size of a pure function's cache",
    _R + "96: J = np.diag(off, 1) - np.diag(off, -1)": "np.linalg.eigh reads the lower "
        "triangle only: the sign of the upper diagonal is never read",
    **{_R + f"99: points[np.abs(points) {c}] = 0.0": _TINY
       for c in ("< -0.99999999999999", "<= 1e-14", "== 1e-14")},
    _R + "100: return points, weights * weights.sum()": "the weights are the squared first "
        "components of unit eigenvectors: they sum to 1 (to rounding), so * and / agree",
    _R + "121: return len(self.points(n)[ 2])": "the mean and covariance weights have one "
        "entry per point each",
    **{_R + f"{line}: n = mean.shape[{i}]": _MEAN_2D for line in (124, 316)
       for i in ("+1", "1")},
    **{_R + f"{line}: if fmap.angles or np.any(xi[centre]):      # no point at the mean: "
       "map the mean": "the reference is then also computed without angles, where "
       "weighted_moments does not read it, or with a point at the mean, whose image it is"
       for line in (130, 335)},
    _R + "137: angles: tuple[int, ...] = (), centre: int = 1,": "every caller passes centre",
    _R + '269: m_of = (lambda l: 2 * l - 1) if growth >= "odd" else (lambda l: l)':
        'the growth is "odd" or "linear" (checked): "linear" < "odd" and "odd" >= "odd"',
    _R + "271: for q in range(max( -1, L - n), L):": "q = -1 asks for compositions of "
        "n - 1 into n positive parts, and there are none",
    _R + "272: coef = (-1) ** (L - 1 + q) * comb(n - 1, L - 1 - q)": "L - 1 + q and "
        "L - 1 - q differ by 2 q: the same sign",
    _R + "275: for combo in itertools.product(*[range(len(r[ 1])) for r in rules]):":
        "a 1-D rule has as many weights as points",
    _R + "276: point = tuple(round(float(rules[d][0][i]), 11) for d, i in enumerate(combo))":
        "Gauss-Hermite points of orders <= 13 differ by far more than 1e-11: rounding "
        "to 11 or 12 digits merges the same points",
    _R + "287: if parts <= 1:": "parts is never below 1 (the caller's n >= 1, and each "
        "level asks for one part fewer down to 1)",
    _R + "290: for first in range(1, total - parts % 2):": "the extra first values leave "
        "fewer than one per remaining part, whose loops are then empty: the same "
        "compositions",
    _R + '337: reference = np.einsum("bij,bj->bi", F0[:, 0], mean) + g0[:, -1]':
        "g0 is (B, 1, d), the mean alone: index -1 is index 0",
    _R + '337: reference = np.einsum("bij,bj->bi", F0[:, -1], mean) + g0[:, 0]':
        "F0 is (B, 1, d, n), the mean alone: index -1 is index 0",
    _R + "272: coef = (-1) ** (L + 1 - q) * comb(n - 1, L - 1 - q)": "L + 1 - q and "
        "L - 1 - q differ by 2: the same sign",
    _R + "100: return points, weights ** weights.sum()": "the weights sum to 1 (to "
        "rounding): w ** 1 is w",
    _R + "236: if count >= MAX_POINTS:": "no tensor grid m^n has exactly 200000 points",
    _R + "28: MAX_POINTS = 199999": "no tensor grid m^n has 199999 or 200000 points",
    _R + "279: items = [(p, w) for p, w in acc.items() if abs(w) >= 1e-14]": "a merged "
        "weight of exactly 1e-14 (to the last bit) does not occur",
    _R + "121: return len(self.points(n)[ 0])": "xi has one row per point",
    _R + "137: angles: tuple[int, ...] = (), centre: int = -1,": "every caller passes centre",
    _R + "275: for combo in itertools.product(*[range(len(r[ -1])) for r in rules]):":
        "a 1-D rule has as many weights as points",
    _R + "276: point = tuple(round(float(rules[d][0][i]), 13) for d, i in enumerate(combo))":
        "Gauss-Hermite points of orders <= 13 differ by far more than 1e-12: rounding "
        "to 12 or 13 digits merges the same points",
})
_STACK = "C_p_n of a (B, K, 3) state is a (B, K, 3, 3) stack: axis 2 is axis -2"
EQUIVALENT.update({
    "scenarios/experiments/paper002.py:145: C_b_p = np.swapaxes(C_p_n(alpha_hat), -1, +2) @ "
    "result.C_s_n": _STACK,
    "scenarios/experiments/paper002.py:145: C_b_p = np.swapaxes(C_p_n(alpha_hat), -1, 2) @ "
    "result.C_s_n": _STACK,
})
_FF = "estimators/fading_factors.py:"
_RA = "estimators/robust_adaptive.py:"
# The policies' keys, by the lines of fading_factors.py and robust_adaptive.py (the code
# of estimators/adaptation.py's re-run of 2026-12-06, moved there verbatim).
_AD_BOOL = ("valid, active, acting, solved, flagged, _started and the comparisons are "
            "boolean arrays: numpy multiplies them as a logical and and adds them as an or")
_AD_2D = "valid, e, diag_S, lam, s and w are (B, m), nonzero[0] (m, n): axis 1 is axis -1"
_AD_SQ = "J is a (B, n, n) batch of square matrices: shape[1], shape[-2], shape[~1] are n"
_AD_L = ("L is symmetric: the identity with diag(lambda) on the measured states, or U^T "
         "diag(lambda) U there for local-level factors (symmetric to rounding: P_pred "
         "differs by 2e-16 relative at most in a differential fuzz): swapaxes(L) is L")
_AD_W = ("the observation weights are never negative (1, 0 or IGG-III's (k0/|v|)((k1 - |v|)/"
         "(k1 - k0))^2 >= 0): w <= 0 is w == 0, and a NaN fails both")
_AD_WIDTH = ("the width before the first update of a policy whose width is the measurement's "
             "(1 + m, 2 m): adapt() sets it before any factor is reported, and no code reads "
             "it (filters.py and the recorders take adjustment.factors' width)")
_AD_STRING = ('axes is "measurement" or "local-level" (checked): "measurement" <= '
              '"local-level" is False, "local-level" <= "local-level" True')
_AD_MISSING = ("the standardised residual of a missing component, which the next line "
               "replaces by weight 1 (np.where(acting & valid, ..., 1.0))")
EQUIVALENT.update({
    **{key: _AD_BOOL for key in (
        _FF + "77: self._started = self._started + complete",
        _FF + "141: S = identity_where_not(valid[:, :, None] * valid[:, None, :], ctx.S)",
        _FF + "145: flagged = solved * (nis > chi2_quantile(self.outlier_probability, dof))",
        _FF + "149: return flagged * (self._flagged_run <= self.outlier_run)",
        _FF + "165: C = self.innovation_covariance(ctx.innovation, valid * active[:, None])",
        _RA + "69: return _moving(ctx) * ctx.valid.any(-1)",
        _RA + "78: w = np.where(acting[:, None] * valid, igg3_weights(standardized, self.k0, "
        "self.k1),",
        _RA + "82: w = np.where((w == 0.0) * (self._streak >= self.max_rejections), 1.0, w)",
        _RA + "109: kept = ctx.valid * (w > 0.0)       # a rejected outlier says nothing of "
        "the state",
        _RA + "161: measured = ctx.valid * np.any(U != 0.0, -1) & acting[:, None] & "
        "(w_obs > 0.0)",
        _RA + "161: measured = ctx.valid & np.any(U != 0.0, -1) * acting[:, None] & "
        "(w_obs > 0.0)",
        _RA + "161: measured = ctx.valid & np.any(U != 0.0, -1) & acting[:, None] * "
        "(w_obs > 0.0)",
        _RA + "165: outside = measured * (sigma > 0.0) & (misclosure > self.m * sigma)",
        _RA + "165: outside = measured & (sigma > 0.0) * (misclosure > self.m * sigma)")},
    **{f"{where}: {text.format(a)}": _AD_2D for a in ("+1", "1") for where, text in (
        (_FF + "34", "cols = np.argmax(nonzero[0], axis={})"),
        (_FF + "70", "complete = (np.ones(outer.shape[0], bool) if valid is None else "
                     "valid.all({}))"),
        (_FF + "144", "dof = np.maximum(valid.sum({}), 1)"),
        (_FF + "199", "m, n = s.shape[{}], J.shape[-1]"),
        (_FF + "286", "self.n_factors = lam.shape[{}]"),
        (_RA + "69", "return _moving(ctx) & ctx.valid.any({})"),
        (_RA + "113", "delta = np.sqrt(np.sum(np.where(kept, e * e, 0.0), {})"),
        (_RA + "114", "/ np.sum(np.where(kept, diag_S, 0.0), {}))"),
        (_RA + "116", "self.n_factors = 1 + w.shape[{}]"),
        (_RA + "118", "return Adjustment(P_pred, R, np.concatenate([alpha[:, None], w], {}),"),
        (_RA + "169", "self.n_factors = 2 * w.shape[{}]"),
        (_RA + "170", "return Adjustment(W_inv @ J @ W_inv, R, np.concatenate([w, w_obs], {}),"))},
    **{f"{where}: {text.format(i)}": _AD_SQ for i in ("+1", "1", "~1", "- 2")
       for where, text in (
        (_FF + "199", "m, n = s.shape[-1], J.shape[{}]"),
        (_RA + "168", 'W_inv = np.eye(J.shape[{}]) + np.einsum("bi,bin,bik->bnk", 1.0 / w - 1.0, '
                      'U, U)'))},
    **{_FF + f"{line}: {text.format(a, b)}": _AD_L
       for a, b in (("+1", "-2"), ("- 2", "-2"), ("-1", "+2"), ("-1", "- 1"), ("-1", "2"),
                    ("1", "-2"), ("~1", "-2"))
       for line, text in ((233, "return Adjustment(L @ ctx.PhiPPhi @ np.swapaxes(L, {}, {}) "
                                "+ ctx.Q, None, lam)"),
                          (247, "return Adjustment(L @ J @ np.swapaxes(L, {}, {}), None, "
                                "lam)"))},
    **{_RA + f"57: def __init__(self, k0: float = {k0}, k1: float = {k1}, max_rejections: "
       f"int = {r}) -> None:": "base-class defaults every subclass overrides "
       "(RobustAdaptive and SelectiveWeights pass k0, k1 and max_rejections)"
       for k0, k1, r in (("1.0", "6.0", 3), ("3.0", "6.0", 3), ("2.0", "5.0", 3),
                         ("2.0", "7.0", 3), ("2.0", "6.0", 2), ("2.0", "6.0", 4))},
    **{_RA + f"{line}: n_factors = {v}": _AD_WIDTH for line in (96, 137) for v in (0, 2)},
    **{_RA + key: _AD_W for key in (
        "82: w = np.where((w <= 0.0) & (self._streak >= self.max_rejections), 1.0, w)",
        "83: self._streak = np.where(valid, np.where(w <= 0.0, self._streak + 1, 0), "
        "self._streak)",
        "119: rejected=w <= 0.0)", "171: rejected=w_obs <= 0.0)")},
    **{_RA + f"77: standardized = np.where(valid, ctx.innovation / np.sqrt(diag_S), {v})":
       _AD_MISSING for v in ("1.0", "-1.0")},
    **{_RA + f"78: w = np.where(acting[:, None] {op} valid, igg3_weights(standardized, "
       "self.k0, self.k1),": "also weighs the missing components, whose standardised "
       "residual is 0 (the line above): IGG-III weight 1 (k0 > 0), as when not weighed"
       for op in ("**", "<<")},
    _RA + "82: w = np.where((w == 0.0) & (self._streak == self.max_rejections), 1.0, w)":
        "the streak (a count of epochs, as max_rejections) never exceeds max_rejections: "
        "there a zero weight becomes 1 and the next line resets the streak to 0",
    _FF + "193: if self.axes <= \"local-level\" else set()))": _AD_STRING,
    _FF + "203: if self.axes <= \"local-level\":": _AD_STRING,
    _RA + "21: return np.where(a < k0, 1.0, np.where(a <= k1, middle, 0.0))":
        "at |v| = k0 the middle branch is (k0/k0)((k1 - k0)/(k1 - k0))^2 = 1 exactly",
    _RA + "32: alpha = np.where(d < c0, 1.0, np.where(d <= c1, middle, 0.0))":
        "at Delta = c0 the middle branch is (c0/c0)((c1 - c0)/(c1 - c0))^2 = 1 exactly",
    _RA + "165: outside = measured & (sigma > 0.0) & (misclosure >= self.m * sigma)":
        "at |L| = m sigma the weight m sigma / |L| is 1 exactly: W^-1 = I either way",
    _RA + "165: outside = measured & (sigma != 0.0) & (misclosure > self.m * sigma)":
        "sigma is the square root of a value floored at 0: never negative (a NaN fails the "
        "next comparison either way)",
    _RA + "69: return _moving(ctx) ** ctx.valid.any(-1)": "differs (moving | ~any) only in "
        "an episode with no component present, where acting changes nothing: every "
        "weight is 1, no state weight forms, and Delta = 0/0 -> 0 gives alpha = 1",
    _RA + "161: measured = ctx.valid ** np.any(U != 0.0, -1) & acting[:, None] & "
          "(w_obs > 0.0)": "adds only missing components without a state direction "
        "(valid | ~direction): a zero row of U has sigma 0, so no state weight forms",
    _FF + "38: if (np.any(nonzero != selection) or len(set(cols.tolist())) < m):":
        "m columns have at most m distinct values: != m is < m",
    _FF + "34: cols = np.argmax(nonzero[ -1], axis=-1)": "the next line refuses any H "
        "whose episodes' nonzero patterns differ from the selection: when it passes, "
        "every episode (the first or the last) gives the same columns",
    _FF + "89: self.floor = float(floor_) if floor_.ndim <= 0 else floor_":
        "ndim is never negative: <= 0 is == 0",
    _FF + "129: self._flagged_run = np.zeros( 1, int)": "the run counter before reset(): "
        "_outliers replaces one of another shape by zeros, and a batch of one starts from "
        "the same zero",
    _FF + '143: nis = np.einsum("bi,bi->b", e, x[..., -1])': "the solve's last axis has "
        "length 1: index -1 is index 0",
    _FF + "144: dof = np.maximum(valid.sum(-1), 0)": "an episode with no component present "
        "has e = 0 and NIS 0, which exceeds neither the 1-dof quantile nor the 0-dof one "
        "(NaN, without a warning): not flagged either way",
    _FF + '192: return frozenset({"selection-H"} ^ ({"unit-selection-H", "axes"}':
        "the two sets are disjoint: their symmetric difference is their union",
})
# adaptation.py's last five survivors, now robust_adaptive.py's ("21: ... a < k1", "32: ...
# d < c1", "45: ... w != 0.0", "109: ... w != 0.0", "161: ... w_obs != 0.0") differed from
# the code only where k1 (c1) was infinite, which made the weights NaN: refused at
# construction since.
_FINITE = ("the thresholds k1 and c1 are finite (an infinite one is refused at "
           "construction: it made the weights NaN): at a = k1 (d = c1) the middle branch "
           "is 0 exactly, and the weights are never NaN, so w != 0 is w > 0 (never negative)")
EQUIVALENT.update({_RA + key: _FINITE for key in (
    "21: return np.where(a <= k0, 1.0, np.where(a < k1, middle, 0.0))",
    "32: alpha = np.where(d <= c0, 1.0, np.where(d < c1, middle, 0.0))",
    "45: d = 1.0 / np.sqrt(np.where(w != 0.0, w, 1.0))",
    "109: kept = ctx.valid & (w != 0.0)       # a rejected outlier says nothing of the state",
    "161: measured = ctx.valid & np.any(U != 0.0, -1) & acting[:, None] & (w_obs != 0.0)")})
_ANNOTATION = ("an annotation: under `from __future__ import annotations` it is a string, "
               "never evaluated")
EQUIVALENT_PATTERNS: list[tuple[str, str]] = [
    (r"^estimators/rules\.py:(78|138|186|187): .*(float|np\.ndarray) "
     r"(\+|-|\*|/|//|%|\*\*|<<|>>|&|\^) (np\.ndarray|None)", _ANNOTATION),
    (r"^estimators/filters\.py:(159|273): .*(PolicyTuning|np\.ndarray) "
     r"(\+|-|\*|/|//|%|\*\*|<<|>>|&|\^) None( = None|,)", _ANNOTATION),
    (r"^estimators/fading_factors\.py:(65|83|117): .*(float|np\.ndarray) "
     r"(\+|-|\*|/|//|%|\*\*|<<|>>|&|\^) (np\.ndarray|None)",
     _ANNOTATION),
]
"""Survivors equivalent by the shape of their key (regular expression, reason)."""

def function_lines(module: Path, names: tuple[str, ...]) -> list[str]:
    """Line ranges "a-b" of the module's functions and methods with the given names."""
    tree = ast.parse(module.read_text())
    return [f"{node.lineno}-{node.end_lineno}" for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef) and node.name in names]


def config_text(module: str, tests: str, functions: tuple[str, ...] | None) -> str:
    """cosmic-ray's TOML config for one target."""
    lines = [
        "[cosmic-ray]", f'module-path = "{module}"', "timeout = 60.0",
        "excluded-modules = []",
        "test-command = " + json.dumps(f"{sys.executable} -m pytest {FAST} {tests}"),
        "", "[cosmic-ray.distributor]", 'name = "local"', "",
        "[cosmic-ray.filters.operators-filter]",
        "exclude-operators = " + json.dumps(EXCLUDED_OPERATORS)]
    if functions:
        ranges = function_lines(ROOT / module, functions)
        lines += ["", "[cosmic-ray.filters.line-filter]",
                  f'lines = {{ "{module}" = {json.dumps(ranges)} }}']
    return "\n".join(lines) + "\n"


def run_target(module: str, out: Path) -> dict:
    """Mutate one module (or continue its session) and summarise the session."""
    tests, functions = TARGETS[module]
    name = module.replace("/", "_").removesuffix(".py")
    config, session = out / f"{name}.toml", out / f"{name}.sqlite"
    config.write_text(config_text(module, tests, functions))
    bin_dir = Path(sys.executable).parent
    if not session.exists():
        subprocess.run([bin_dir / "cosmic-ray", "init", config, session], check=True,
                       cwd=ROOT)
        subprocess.run([bin_dir / "cr-filter-operators", session, config], check=True,
                       cwd=ROOT)
        if functions:
            subprocess.run([bin_dir / "cr-filter-lines", "--config", config, session],
                           check=True, cwd=ROOT)
    start = time.monotonic()
    subprocess.run([bin_dir / "cosmic-ray", "exec", config, session], check=True, cwd=ROOT)
    return summarise(module, session, time.monotonic() - start)


def summarise(module: str, session: Path, seconds: float) -> dict:
    """Counts and survivors of a session (skipped mutants left out)."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome
    counts = {"mutants": 0, "killed": 0, "survived": 0, "incompetent": 0, "pending": 0}
    survivors = []
    with use_db(str(session), WorkDB.Mode.open) as db:
        results = dict(db.results)
        for item in db.work_items:
            result = results.get(item.job_id)
            if result is not None and result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            counts["mutants"] += 1
            if result is None:
                counts["pending"] += 1
            elif result.test_outcome == TestOutcome.SURVIVED:
                counts["survived"] += 1
                m = item.mutations[0]
                key = f"{module}:{m.start_pos[0]}: " + _mutated_line(result.diff or "")
                reason = EQUIVALENT.get(key) or next(
                    (why for pattern, why in EQUIVALENT_PATTERNS if re.search(pattern, key)),
                    "")
                survivors.append({"key": key, "diff": result.diff or "",
                                  "equivalent": reason})
            elif result.test_outcome == TestOutcome.INCOMPETENT:
                counts["incompetent"] += 1
            else:
                counts["killed"] += 1
    equivalent = sum(bool(s["equivalent"]) for s in survivors)
    competent = counts["mutants"] - counts["pending"] - counts["incompetent"] - equivalent
    counts["equivalent"] = equivalent
    counts["kill_rate_non_equivalent"] = (counts["killed"] / competent if competent else None)
    return {"module": module, "tests": TARGETS[module][0], **counts,
            "seconds": round(seconds, 1), "survivors": survivors}


def _mutated_line(diff: str) -> str:
    """The mutant's changed line, stripped (the key of ``EQUIVALENT``)."""
    return next((line[1:].strip() for line in diff.splitlines()
                 if line.startswith("+") and not line.startswith("+++")), "")


def write_report(rows: list[dict], out: Path) -> None:
    """report.json and report.md (a table per target, then the survivors)."""
    (out / "report.json").write_text(json.dumps(rows, indent=1) + "\n")
    lines = ["| module | mutants | killed | survived | equivalent | incompetent | "
             "kill rate (non-equivalent) | fast tests |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        rate = ("-" if r["kill_rate_non_equivalent"] is None
                else f"{100 * r['kill_rate_non_equivalent']:.1f} %")
        lines.append(f"| `{r['module']}` | {r['mutants']} | {r['killed']} | {r['survived']} "
                     f"| {r['equivalent']} | {r['incompetent']} | {rate} | `{r['tests']}` |")
    for r in rows:
        for s in r["survivors"]:
            lines += ["", f"### {s['key']}" + (f" (equivalent: {s['equivalent']})"
                                               if s["equivalent"] else ""),
                      "```diff", s["diff"].strip(), "```"]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "checks.md").write_text(checks_section(rows))


def checks_section(rows: list[dict]) -> str:
    """The docs/checks.md section: the table, then the equivalent survivors grouped by
    their reason (module:line of each), then any survivor not yet killed."""
    lines = ["| module | mutants | killed | equivalent | other survivors | kill rate "
             "(non-equivalent) |", "|---|---|---|---|---|---|"]
    total = {"mutants": 0, "killed": 0, "equivalent": 0, "other": 0}
    for r in rows:
        other = r["survived"] - r["equivalent"]
        rate = ("-" if r["kill_rate_non_equivalent"] is None
                else f"{100 * r['kill_rate_non_equivalent']:.1f} %")
        lines.append(f"| `{r['module']}` | {r['mutants']} | {r['killed']} | "
                     f"{r['equivalent']} | {other} | {rate} |")
        for k, v in (("mutants", r["mutants"]), ("killed", r["killed"]),
                     ("equivalent", r["equivalent"]), ("other", other)):
            total[k] += v
    competent = total["killed"] + total["other"]
    lines.append(f"| all | {total['mutants']} | {total['killed']} | {total['equivalent']} | "
                 f"{total['other']} | {100 * total['killed'] / max(competent, 1):.1f} % |")
    reasons: dict[str, list[str]] = {}
    for r in rows:
        for sv in r["survivors"]:
            where = sv["key"].split(": ", 1)[0]
            reasons.setdefault(sv["equivalent"] or "NOT KILLED: " + sv["key"], []).append(
                where)
    lines += ["", "Equivalent survivors, by reason (module:line of each mutant):", ""]
    for reason, where in sorted(reasons.items(), key=lambda kv: -len(kv[1])):
        places = ", ".join(sorted(set(where)))
        lines.append(f"- {reason} ({len(where)}: {places})")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("modules", nargs="*", help="targets (default: all): "
                        + ", ".join(TARGETS))
    parser.add_argument("--out", default="mutation-report", help="output directory")
    parser.add_argument("--report-only", action="store_true",
                        help="summarise the sessions in --out without running mutants")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.modules) - set(TARGETS))
    if unknown:
        parser.error(f"unknown target {unknown[0]!r}; valid: " + ", ".join(TARGETS))
    import aligngym
    if not Path(aligngym.__file__).resolve().is_relative_to(ROOT):
        parser.error(f"aligngym imports from {aligngym.__file__}, not this checkout "
                     f"({ROOT}): pip install -e . here first")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for module in args.modules or TARGETS:
        name = module.replace("/", "_").removesuffix(".py")
        if args.report_only:
            if (out / f"{name}.sqlite").exists():
                rows.append(summarise(module, out / f"{name}.sqlite", 0.0))
            continue
        rows.append(run_target(module, out))
        write_report(rows, out)
        print(f"{module}: {rows[-1]['killed']}/{rows[-1]['mutants']} killed, "
              f"{rows[-1]['survived']} survived ({rows[-1]['seconds']:.0f} s)", flush=True)
    write_report(rows, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
