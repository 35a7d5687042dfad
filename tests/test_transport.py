"""Large arrays between a campaign's processes as shared files
(``scenarios.campaign.transport``): the same arrays arrive, mapped rather than copied; the
pipe where no file can be written; no file left behind."""
import glob
import mmap
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
            "small": np.arange(5.0), "objects": np.array([{"a": 1}] * 200_000, dtype=object)}


def _make(name: str) -> np.ndarray:
    return _arrays()[name]


def _mapped(array: np.ndarray) -> bool:
    base = array
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, memoryview):
        base = base.obj
    return isinstance(base, mmap.mmap)


def _left() -> list[str]:
    return glob.glob(os.path.join(transport.SHARED_DIR, transport._prefix(os.getpid()) + "*"))


def _send(names):
    with transport.shared_arrays():
        with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
            return dict(zip(names, pool.map(_make, names)))


def test_large_arrays_arrive_the_same_mapped_and_leave_no_file():
    sent = _arrays()
    got = _send(list(sent))
    for name, array in sent.items():
        assert got[name].dtype == array.dtype and got[name].shape == array.shape, name
        if array.dtype.hasobject:
            assert list(got[name]) == list(array)
        else:
            np.testing.assert_array_equal(got[name], array)
    assert {n for n, a in got.items() if _mapped(a)} == {"large", "fortran", "record", "ints"}
    got["large"][0, 0] = 7.0                                     # writable, in this process
    assert _left() == []
    from multiprocessing.reduction import ForkingPickler
    assert np.ndarray not in ForkingPickler._extra_reducers       # only within the block


def test_without_room_or_a_directory_the_arrays_take_the_pipe(monkeypatch, tmp_path):
    monkeypatch.setattr(transport, "SHARED_DIR", str(tmp_path / "missing"))
    got = _send(["large"])
    np.testing.assert_array_equal(got["large"], _arrays()["large"])
    assert not _mapped(got["large"])
    monkeypatch.setattr(transport, "SHARED_DIR", str(tmp_path))
    monkeypatch.setattr(transport, "ROOM_FACTOR", 1e12)           # never room enough
    got = _send(["large"])
    assert not _mapped(got["large"]) and list(tmp_path.iterdir()) == []


def test_a_file_no_process_mapped_is_removed_when_the_block_ends():
    with transport.shared_arrays():
        rebuild, (path, dtype, shape) = transport._reduce(_arrays()["large"])
        assert os.path.exists(path) and _left() == [path]
    assert not os.path.exists(path)
