"""The command's exit (``cli._finish_collections``, registered once per process): the
garbage left at exit is collected (its finalizers run), then the live objects are frozen
out of the collector's reach before the interpreter's shutdown."""
import subprocess
import sys

from aligngym.scenarios import cli

EXITING = """
import atexit, gc
# registered before the command's handler, so it runs after it (atexit runs in reverse)
atexit.register(lambda: print("frozen", gc.get_freeze_count()))
from aligngym.scenarios.cli import main
main(["bench", "paper003", "--resume"])

class Cycle:
    def __init__(self):
        self.me = self
    def __del__(self):
        print("finalized")

Cycle()                  # garbage in a cycle: only a collection finalizes it
"""


def test_a_command_process_ends_collected_then_frozen():
    done = subprocess.run([sys.executable, "-c", EXITING], capture_output=True, text=True,
                          timeout=120)
    assert "--resume needs --out" in done.stderr
    finalized, frozen = done.stdout.split()[0], done.stdout.split()[-1]
    assert finalized == "finalized"        # collected at exit, before the freeze
    assert int(frozen) > 10_000            # every live object, not a handful


def test_the_exit_handler_is_registered_once_and_not_run_before_exit(monkeypatch):
    import atexit
    import gc
    registered = []
    monkeypatch.setattr(atexit, "register", registered.append)
    monkeypatch.setattr(cli, "_EXIT_FROZEN", False)
    frozen = gc.get_freeze_count()
    for _ in range(2):
        assert cli.main(["bench", "paper003", "--resume"]) == 2
    assert registered == [cli._finish_collections]
    assert gc.get_freeze_count() == frozen  # nothing frozen while the process goes on
