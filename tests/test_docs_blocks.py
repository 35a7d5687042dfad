"""Every Python code block of the README and docs/ runs as shown (issue 46): each block
is executed as a user would paste it, with the episode counts cut to 1 (``run_campaign``
and ``assert_alignment`` see at most 1); a block followed by a "prints" block must print
its filters with the same status columns (converged, not converged, diverged, lost), and
a block that defines ``test_*`` functions has them called. ``my_module:entry``, the
user's module the README names, is provided as the third-degree cubature filter."""
from __future__ import annotations

import contextlib
import io
import re
import sys
import types
from pathlib import Path

import pytest

import aligngym
from aligngym.estimators.catalogue import FILTERS

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", re.S | re.M)
MAX_EPISODES = 1


def blocks() -> list[tuple[str, str, str | None]]:
    """(id, code, the output shown after it or None) of every Python block."""
    out = []
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        found = list(FENCE.finditer(path.read_text()))
        for i, match in enumerate(found):
            if match.group(1) != "python":
                continue
            shown = None
            if i + 1 < len(found) and found[i + 1].group(1) == "":
                between = path.read_text()[match.end():found[i + 1].start()]
                if between.strip().startswith("prints"):
                    shown = found[i + 1].group(2)
            out.append((f"{path.name}:{i}", match.group(2), shown))
    return out


def status_rows(text: str) -> dict[str, list[str]]:
    """filter -> its four status percentages, from a table's "mean" rows."""
    rows = {}
    for line in text.splitlines():
        m = re.match(r"^(\S+)\s+mean\s+\S+\s+\S+\s+\S+\s+(\d+%)\s+(\d+%)\s+(\d+%)\s+(\d+%)",
                     line)
        if m:
            rows[m.group(1)] = list(m.groups()[1:])
    return rows


@pytest.fixture
def user_world(monkeypatch):
    """Episode counts cut to MAX_EPISODES; my_module:entry; registrations undone."""
    from aligngym.estimators.adaptation import NoAdaptation
    from aligngym.estimators.rules import CubatureRule
    from aligngym.scenarios import campaign
    from aligngym.scenarios import registry
    real = campaign.run_campaign

    def short(experiment, episodes=None, *args, **kwargs):
        kwargs.setdefault("progress", False)
        return real(experiment, min(episodes or MAX_EPISODES, MAX_EPISODES), *args, **kwargs)

    monkeypatch.setattr(campaign, "run_campaign", short)
    monkeypatch.setattr(aligngym, "run_campaign", short)
    module = types.ModuleType("my_module")
    module.entry = lambda: aligngym.FilterEntry(CubatureRule, NoAdaptation, "cubature")
    monkeypatch.setitem(sys.modules, "my_module", module)
    filters, experiments = set(FILTERS), set(registry._REGISTERED)
    yield
    for name in set(FILTERS) - filters:
        FILTERS.pop(name)
    for name in set(registry._REGISTERED) - experiments:
        registry._REGISTERED.pop(name)


BLOCKS = blocks()


def test_the_docs_have_python_blocks():
    assert len(BLOCKS) >= 4, [b[0] for b in BLOCKS]


@pytest.mark.parametrize("code, shown", [b[1:] for b in BLOCKS], ids=[b[0] for b in BLOCKS])
def test_a_docs_block_runs_as_shown(code, shown, user_world, monkeypatch):
    module = types.ModuleType("docs_block")        # a module, as a user's script is
    monkeypatch.setitem(sys.modules, "docs_block", module)
    namespace = module.__dict__
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "docs_block", "exec"), namespace)
        for name, value in list(namespace.items()):
            if name.startswith("test_") and callable(value):
                value()
    if shown is not None:
        expected = status_rows(shown)
        assert expected, "the shown output has no table rows"
        assert status_rows(printed.getvalue()) == expected, printed.getvalue()


def test_the_external_filter_example_marks_the_fifth_degree_rule_lost(user_world,
                                                                      monkeypatch):
    """examples/external_filter.py (README, "Your own filter"): the fifth-degree cubature
    rule, points at sqrt(12) sigma = 208 deg of heading from the 58.5 deg start, is lost
    in every episode; the EKF, the UKF and the sparse grid converge."""
    import runpy
    monkeypatch.setattr(sys, "argv", ["external_filter.py", "--episodes", "1"])
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        runpy.run_path(str(ROOT / "examples" / "external_filter.py"), run_name="__main__")
    rows = status_rows(printed.getvalue())
    assert rows["cqkf-5"] == ["0%", "0%", "0%", "100%"], printed.getvalue()
    for name in ("ekf", "ukf", "sghkf-2"):
        assert rows[name] == ["100%", "0%", "0%", "0%"], printed.getvalue()


def test_the_readmes_main_command_runs_twice(tmp_path, monkeypatch, capsys):
    """The README's first set-up command (its `aligngym ...` part, after `pip install -e .
    &&`), with 1 episode and a 60 s fine alignment, run twice in a row in a fresh
    directory: both exit 0, the second continues the same campaign and prints the same
    tables."""
    import shlex

    from aligngym.scenarios.cli import main
    setup = (ROOT / "README.md").read_text().split("## Set-up", 1)[1]
    command = next(m.group(2) for m in FENCE.finditer(setup)).strip()
    assert command.startswith("pip install -e . && aligngym bench "), command
    argv = shlex.split(command.split("&&", 1)[1])[1:]
    argv[argv.index("--episodes") + 1] = "1"
    argv += ["--workers", "1", "--no-figures", "--set", "fine_duration=60",
             "--set", "coarse_duration=30", "--set", "t_k1=10", "--set", "t_k2=30"]
    monkeypatch.chdir(tmp_path)
    printed = []
    for _ in range(2):
        assert main(argv) == 0
        printed.append(capsys.readouterr())
    assert "holds this campaign already" in printed[1].err
    assert printed[0].out.splitlines()[:-1] == printed[1].out.splitlines()[:-1]
