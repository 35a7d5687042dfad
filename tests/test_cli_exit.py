"""The command's exit: its objects are frozen out of the garbage collector's reach before
the interpreter's shutdown (``cli._no_collection_at_exit``), once per process."""
import subprocess
import sys

from aligngym.scenarios import cli


def test_a_command_process_ends_with_its_objects_frozen():
    # registered before the command's handler, so it runs after it (atexit runs in reverse)
    code = ("import atexit, gc\n"
            "atexit.register(lambda: print('frozen', gc.get_freeze_count()))\n"
            "from aligngym.scenarios.cli import main\n"
            "main(['bench', 'paper003', '--resume'])\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert "--resume needs --out" in done.stderr
    count = int(done.stdout.split("frozen")[-1])
    assert count > 10_000            # every object the command left, not a handful


def test_the_exit_freeze_is_registered_once(monkeypatch, capsys):
    import atexit
    import gc
    registered = []
    monkeypatch.setattr(atexit, "register", registered.append)
    monkeypatch.setattr(cli, "_EXIT_FROZEN", False)
    for _ in range(2):
        assert cli.main(["bench", "paper003", "--resume"]) == 2
    assert registered == [gc.freeze]
