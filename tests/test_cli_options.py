"""The command line's number and count options: a value outside its range (below the
minimum, NaN, infinite, not a number) is refused before any work, with exit status 2 and
one line naming the option, its range and the value as written."""
import pytest

from aligngym.scenarios.cli import main


@pytest.mark.parametrize("argv, message", [
    (["bench", "paper003", "--episodes", "0"], "--episodes must be an integer >= 1, got 0"),
    (["reproduce", "paper003", "--episodes", "-3"],
     "--episodes must be an integer >= 1, got -3"),
    (["bank", "ship-sway-rotary", "--out", "b", "--first", "-1"],
     "--first must be an integer >= 0, got -1"),
    (["regress", "--workers", "0"], "--workers must be an integer >= 1, got 0"),
    (["bench", "paper003", "--episodes", "2.5"],
     "--episodes must be an integer >= 1, got '2.5'"),
    (["simulate", "ship-sway-rotary", "--duration", "nan"], "--duration must be > 0, got nan"),
    (["simulate", "ship-sway-rotary", "--imu-rate", "inf"], "--imu-rate must be > 0, got inf"),
    (["render", "ship-sway-rotary", "--start", "-1", "--out", "x.png"],
     "--start must be >= 0, got -1"),
    (["fidelity", "ship-sway-rotary", "--duration", "0"], "--duration must be > 0, got 0"),
    (["render", "ship-sway-rotary", "--fps", "fast", "--out", "x.mp4"],
     "--fps must be a number, got 'fast'"),
])
def test_an_option_out_of_its_range_is_one_line_exit_2(argv, message, capsys, tmp_path,
                                                       monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith(f"error: argument {argv[argv.index(message.split()[0])]}: "
                            f"{message}"), err[-1]
    assert not any(tmp_path.iterdir())             # refused before any work
