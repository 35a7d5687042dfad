"""An experiment is a declaration: its roles (preparation, truth map, summary, tables,
plots, the episode type) are class attributes, and its methods hold only its science. No
method of a shipped experiment, nor of the test-only DVL experiment (which is not a
paper's subclass), is a one-line forward: a body that only returns a call whose
arguments are the method's own parameters, or only returns a module-level name or one of
its own settings."""
import ast
import inspect
import textwrap
from dataclasses import fields

import pytest

from aligngym.scenarios import registry
from aligngym.scenarios.campaign import Experiment, PreparedEpisode
from aligngym.scenarios.experiments import experiment_class, paper003

from dvl_experiment import DvlAidedExperiment


def forwards(cls: type) -> list[str]:
    """The methods defined in cls's own body that only forward (see the module
    docstring)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    out = []
    for node in tree.body[0].body:
        if not isinstance(node, ast.FunctionDef):
            continue
        body = [s for s in node.body
                if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))]
        if len(body) != 1 or not isinstance(body[0], ast.Return) or body[0].value is None:
            continue
        value = body[0].value
        params = {a.arg for a in node.args.args + node.args.kwonlyargs}
        if isinstance(value, ast.Call):
            args = value.args + [k.value for k in value.keywords]
            if all(isinstance(a, ast.Name) and a.id in params for a in args):
                out.append(node.name)
        elif isinstance(value, ast.Name) and value.id not in params:
            out.append(node.name)                    # returns a module-level name
        elif (isinstance(value, ast.Attribute) and isinstance(value.value, ast.Name)
              and value.value.id in ("self", "cls")):
            out.append(node.name)                    # returns one of its own attributes
    return out


CLASSES = [experiment_class(name) for name in registry.experiment_names()
           if name.startswith("paper")] + [DvlAidedExperiment]


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_no_experiment_method_only_forwards(cls):
    assert issubclass(cls, Experiment)
    assert forwards(cls) == []
    assert callable(cls.preparation) and issubclass(cls.episode_class, PreparedEpisode)


def test_the_check_finds_forwards():
    class Forwarding(DvlAidedExperiment):
        @property
        def episode_class(self):
            return DvlAidedExperiment

        def summary(self, result):
            """The summary."""
            return paper003.coarse_starts(result)

        def start_errors(self, episodes):
            return paper003.coarse_starts(episodes)

        def nees_dof(self):
            return self.state_count

        def model(self, episodes, start_error, variant=""):
            return paper003.start_attitude(episodes, start_error, variant=variant, step=1.0)

    assert forwards(Forwarding) == ["episode_class", "summary", "start_errors", "nees_dof"]


def test_the_dvl_experiment_is_not_a_papers_subclass():
    assert not any(issubclass(DvlAidedExperiment, experiment_class(name))
                   for name in registry.experiment_names() if name.startswith("paper"))


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
def test_every_settings_type_resolves(cls):
    """validate_settings checks a setting's type and range from the class's resolved
    annotations: an annotation of the base that does not resolve at run time (a name
    imported for type checkers only) would leave every setting unchecked."""
    import typing

    from aligngym.scenarios.config import SettingError
    hints = typing.get_type_hints(cls)          # raises where an annotation does not resolve
    assert all(f.name in hints for f in fields(cls))
    with pytest.raises(SettingError, match="rms_window"):
        cls(rms_window=-1.0)                    # declared > 0: checked
    with pytest.raises(SettingError, match="rms_window"):
        cls(rms_window="60")                    # a string for a number: checked
