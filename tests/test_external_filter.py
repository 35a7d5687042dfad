"""Users' own filters (the public API in ``aligngym``): a rule written outside the
package runs in a campaign, in ``scenarios.evaluate`` and on the command line as
``module.path:factory``, with the same numbers as the catalogue's filter it re-implements
(third-degree cubature: +-sqrt(n) e_j, weights 1 / 2n)."""
import json
import textwrap

import numpy as np
import pytest

import aligngym
from aligngym.estimators.catalogue import FILTERS, UnknownFilter, filter_entry
from aligngym.scenarios.campaign import run_campaign


class UserCubature(aligngym.SigmaPointRule):
    """Third-degree spherical-radial cubature, written from its definition."""

    name = "user-cubature"

    def _points(self, n):
        xi = np.sqrt(n) * np.concatenate([np.eye(n), -np.eye(n)])
        return xi, np.full(2 * n, 0.5 / n)


@pytest.fixture
def user_filter():
    aligngym.register_filter("user-ckf", UserCubature, description="cubature, from a test")
    yield "user-ckf"
    FILTERS.pop("user-ckf", None)


def test_a_user_rule_equals_the_catalogues_in_a_campaign(user_filter):
    exp = aligngym.experiment("paper002", fine_duration=120.0)
    result = run_campaign(exp, episodes=2, seed=4, filters=["ckf", user_filter],
                          workers=1, progress=False)
    ckf, user = result.runs
    assert user.filter == user_filter
    np.testing.assert_allclose(user.error_n, ckf.error_n, rtol=0, atol=1e-12)
    np.testing.assert_allclose(user.result.P, ckf.result.P, rtol=1e-10, atol=1e-20)
    assert "user-ckf" in aligngym.filter_names()


def test_a_user_rule_runs_in_the_env_and_evaluate(user_filter):
    from aligngym.scenarios.env import evaluate
    kwargs = {"episode_length": 60.0}
    ours = evaluate("aligngym/ShipSwayRotary-v1", user_filter, 1, seed=2, **kwargs)
    theirs = evaluate("aligngym/ShipSwayRotary-v1", "ckf", 1, seed=2, **kwargs)
    assert not ours[0]["diverged"]
    for a, b in zip(ours, theirs):
        for key, value in a.items():
            if isinstance(value, float) and key != "ms_per_epoch":    # timing
                assert value == pytest.approx(b[key], rel=1e-9, abs=1e-12), key


def test_module_factory_on_the_command_line(tmp_path, monkeypatch):
    """--filters module.path:factory, the module in a directory of the user's: the same
    numbers as the built-in CKF. The loading is under test, not the alignment: 60 s of
    fine alignment (bench --set), 60 epochs of the same cubature steps."""
    from aligngym.scenarios.cli import main
    (tmp_path / "my_filters.py").write_text(textwrap.dedent('''
        import numpy as np
        import aligngym

        class Cubature(aligngym.SigmaPointRule):
            name = "cli-cubature"

            def _points(self, n):
                return (np.sqrt(n) * np.concatenate([np.eye(n), -np.eye(n)]),
                        np.full(2 * n, 0.5 / n))

        def entry():
            return aligngym.FilterEntry(Cubature, aligngym.NoAdaptation, "from a file")
        '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "summary.json"
    code = main(["bench", "paper002", "--episodes", "2", "--seed", "4", "--filters",
                 "ckf,my_filters:entry", "--json", str(out), "--set", "fine_duration=60"])
    assert code in (0, None)
    fine = json.loads(out.read_text())["fine"]
    ours, theirs = fine["my_filters:entry"], fine["ckf"]
    for stat in ("mean_arcmin", "std_arcmin", "rms_arcmin"):
        np.testing.assert_allclose(ours[stat], theirs[stat], atol=1e-9)
    FILTERS.pop("my_filters:entry", None)


@pytest.mark.parametrize("call, message", [
    (lambda: aligngym.register_filter("ukf", UserCubature), "built-in"),
    (lambda: aligngym.register_filter("my filter", UserCubature), "without spaces"),
    (lambda: aligngym.register_filter("x", UserCubature()), "factories"),
    (lambda: aligngym.register_filter("sghkf-2", UserCubature), "built-in"),
])
def test_bad_registrations_are_one_line_errors(call, message):
    with pytest.raises((ValueError, TypeError)) as error:
        call()
    assert message in str(error.value) and "\n" not in str(error.value)


def test_an_unimportable_factory_is_a_one_line_error():
    with pytest.raises(UnknownFilter) as error:
        filter_entry("no_such_module_here:factory")
    assert "cannot import" in str(error.value) and "\n" not in str(error.value)


def test_factories_may_return_a_rule_class_and_their_errors_are_one_line(tmp_path,
                                                                         monkeypatch):
    (tmp_path / "factories.py").write_text(textwrap.dedent('''
        from aligngym.estimators.rules import CubatureRule

        def rule_class():
            return CubatureRule

        def broken():
            raise RuntimeError("no licence")
        '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    assert filter_entry("factories:rule_class").rule().name == "cubature"
    with pytest.raises(UnknownFilter) as error:
        filter_entry("factories:broken")
    assert "RuntimeError: no licence" in str(error.value) and "\n" not in str(error.value)
    FILTERS.pop("factories:rule_class", None)
