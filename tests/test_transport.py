"""Large arrays between a campaign's processes as shared files
(``scenarios.campaign.transport``): the same arrays arrive, mapped rather than copied; the
pipe where no file can be written; no file left behind."""
import glob
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from aligngym.scenarios.campaign import transport

pytestmark = pytest.mark.skipif(not os.path.isdir(transport.SHARED_DIR),
                                reason="no shared-memory directory on this platform")


def _arrays():
    rng = np.random.default_rng(3)
    large = rng.normal(size=(300, 500))                          # 1.2 MB
    record = np.zeros(200_000, dtype=[("t", "f8"), ("k", "i4")])
    record["t"], record["k"] = rng.normal(size=200_000), np.arange(200_000)
    return {"large": large, "fortran": np.asfortranarray(large), "view": large[:, ::2],
            "record": record, "ints": np.arange(400_000, dtype=np.int32),
            "times": np.arange(200_000).astype("datetime64[s]"),
            "small": np.arange(5.0), "objects": np.array([{"a": 1}] * 200_000, dtype=object)}


def _make(name: str) -> np.ndarray:
    return _arrays()[name]


def _left() -> list[str]:
    return glob.glob(os.path.join(transport.SHARED_DIR, transport._prefix(os.getpid()) + "*"))


def _send(names):
    """The named arrays made in forked workers, and how many came as shared files."""
    before = transport.RECEIVED
    with transport.shared_arrays():
        with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
            got = dict(zip(names, pool.map(_make, names)))
    return got, transport.RECEIVED - before


def test_large_arrays_arrive_the_same_through_files_and_leave_none():
    """Large arrays of numbers and records come as files, in their order (C or Fortran);
    small arrays (a 0.6 MB view), object and datetime arrays come through the pipe; all
    arrive equal, writable; no file is left and the reducer is gone after the block."""
    sent = _arrays()
    got, files = _send(list(sent))
    for name, array in sent.items():
        assert got[name].dtype == array.dtype and got[name].shape == array.shape, name
        if array.dtype.hasobject:
            assert list(got[name]) == list(array)
        else:
            np.testing.assert_array_equal(got[name], array)
    assert files == 4                        # large, fortran, record, ints
    assert got["fortran"].flags.f_contiguous and got["large"].flags.c_contiguous
    got["large"][0, 0] = 7.0
    assert _left() == []
    from multiprocessing.reduction import ForkingPickler
    assert np.ndarray not in ForkingPickler._extra_reducers       # only within the block


def test_without_room_or_a_directory_the_arrays_take_the_pipe(monkeypatch, tmp_path):
    monkeypatch.setattr(transport, "SHARED_DIR", str(tmp_path / "missing"))
    got, files = _send(["large"])
    np.testing.assert_array_equal(got["large"], _arrays()["large"])
    assert files == 0
    monkeypatch.setattr(transport, "SHARED_DIR", str(tmp_path))
    monkeypatch.setattr(transport, "ROOM_FACTOR", 1e12)           # never room enough
    got, files = _send(["large"])
    assert files == 0 and list(tmp_path.iterdir()) == []


def test_files_of_a_killed_campaign_are_removed_by_the_next(tmp_path, monkeypatch):
    """A file left by a process that is gone (killed mid-campaign) is removed when the
    next block starts; a live process's file is kept."""
    monkeypatch.setattr(transport, "SHARED_DIR", str(tmp_path))
    import subprocess
    dead = subprocess.Popen(["true"])
    dead.wait()
    orphan = tmp_path / f"aligngym-{dead.pid}-x"
    live = tmp_path / f"aligngym-{os.getppid()}-y"               # another live process's
    orphan.write_bytes(b"1")
    live.write_bytes(b"1")
    with transport.shared_arrays():
        pass
    assert not orphan.exists() and live.exists()


def test_a_file_no_process_read_is_removed_when_the_block_ends():
    with transport.shared_arrays():
        rebuild, (path, *_) = transport._reduce(_arrays()["large"])
        assert os.path.exists(path) and _left() == [path]
    assert not os.path.exists(path)
