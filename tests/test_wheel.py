"""The installed package as a user gets it: a wheel holds one top-level package,
``aligngym`` (models, sensors, estimators and scenarios inside it, the scenario files and
regression baselines as package data), and works from a directory whose own ``models/``,
``sensors/``, ``estimators/`` and ``scenarios/`` packages would shadow generic names."""
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SUBPACKAGES = ("models", "sensors", "estimators", "scenarios")


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(wheel path, the venv's python) : the project's wheel installed without its
    dependencies into a fresh venv whose path ends with this interpreter's site-packages
    (for numpy, MuJoCo, ...): a ``.pth`` file naming them, so that the test works from a
    venv (whose packages ``system_site_packages`` would not see: it sees the base
    interpreter's) as from a system Python; the venv's own aligngym comes first on its
    path, and the running environment's editable aligngym is not loaded (a path in a
    ``.pth`` file is not a site directory: its own ``.pth`` files are not run). The
    wheel is built with this environment's setuptools (the test extra's), not in an
    isolated build environment as pip would for a user: the same files, 2 s sooner."""
    tmp = tmp_path_factory.mktemp("wheel")
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps",
                            "--no-build-isolation", "-w", str(tmp), str(ROOT)],
                           capture_output=True, text=True)
    assert build.returncode == 0, (build.stderr
                                   + "\n(setuptools >= 70.1: pip install -e '.[test]')")
    wheel = next(tmp.glob("aligngym-*.whl"))
    env = tmp / "venv"
    venv.EnvBuilder(system_site_packages=False, with_pip=False).create(env)
    python = env / "bin" / "python"
    purelib = subprocess.run([str(python), "-c", "import sysconfig; "
                              "print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    paths = sysconfig.get_paths()
    Path(purelib, "running-interpreter.pth").write_text(
        "".join(f"{p}\n" for p in dict.fromkeys((paths["purelib"], paths["platlib"]))))
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q",
                    "--no-deps", str(wheel)], check=True, capture_output=True)
    return wheel, python


def test_the_wheel_holds_aligngym_alone_with_its_data(installed):
    wheel, _ = installed
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {"aligngym", wheel.name.split("-py3")[0]
                                                + ".dist-info"}
    for sub in SUBPACKAGES:                 # every package of the source folders
        for init in (ROOT / sub).rglob("__init__.py"):
            assert f"aligngym/{init.relative_to(ROOT).as_posix()}" in names
    assert "aligngym/scenarios/data/static-large-azimuth.toml" in names
    assert "aligngym/scenarios/data/baselines/regress_paper002.json" in names


def venv_cli(python, *args: str) -> list[str]:
    """The command line of the venv's aligngym."""
    return [str(python), "-m", "aligngym.scenarios.cli", *args]


@pytest.fixture
def users_directory(tmp_path):
    """A working directory with its own models/, sensors/, estimators/ and scenarios/."""
    for sub in SUBPACKAGES:
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "__init__.py").write_text("OWNER = 'the user'\n")
    return tmp_path


def test_a_users_own_packages_do_not_shadow_aligngym(installed, users_directory):
    """From a directory with its own models/ ... scenarios/: import aligngym and its
    subpackages from the venv, and a two-episode bench of paper 002."""
    _, python = installed
    code = ("import sys, aligngym, aligngym.models.attitude, aligngym.scenarios.campaign; "
            "import models; assert models.OWNER == 'the user'; "
            "assert aligngym.__file__.startswith(sys.prefix), aligngym.__file__; "
            "assert aligngym.models.attitude.__file__.startswith(sys.prefix); "
            "print(aligngym.run_campaign.__module__)")
    run = subprocess.run([str(python), "-c", code], cwd=users_directory, capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "aligngym.scenarios.campaign.engine"
    bench = subprocess.run(venv_cli(python, "bench", "paper002", "--episodes", "2",
                                    "--filters", "ekf", "--workers", "1", "--json", "s.json"),
                           cwd=users_directory, capture_output=True, text=True)
    assert bench.returncode == 0, bench.stderr
    assert (users_directory / "s.json").is_file()


def test_paper002_regress_from_the_wheel(installed, users_directory):
    """Paper 002's regression campaign from the installed wheel, in the user's directory,
    against the shipped baseline: aligngym regress's only run of paper 002 in the suite
    (tests/test_regress.py leaves it here, FROM_THE_WHEEL)."""
    _, python = installed
    regress = subprocess.run(venv_cli(python, "regress", "--papers", "paper002",
                                      "--workers", "1"),
                             cwd=users_directory, capture_output=True, text=True)
    assert regress.returncode == 0, regress.stdout + regress.stderr
    assert "paper002: 66 metrics, 0 beyond tolerance" in regress.stdout


def test_every_module_imports_under_aligngym_only():
    """Importing every module of the package (from the checkout, as the suite runs)
    loads no top-level models/sensors/estimators/scenarios: no module still imports the
    old names, which would load a second copy of the code beside aligngym's."""
    code = ("import pkgutil, sys, importlib, aligngym; "
            "[importlib.import_module(m.name) for m in "
            "pkgutil.walk_packages(aligngym.__path__, 'aligngym.')]; "
            "importlib.import_module('aligngym.models'); "
            "[importlib.import_module(m.name) for sub in ('models', 'sensors', "
            "'estimators', 'scenarios') for m in pkgutil.walk_packages("
            "importlib.import_module('aligngym.' + sub).__path__, f'aligngym.{sub}.')]; "
            "print(sorted(n for n in sys.modules if n.split('.')[0] in "
            f"{SUBPACKAGES!r}))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
