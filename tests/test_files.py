"""Finished files: written whole or not at all, and synced ahead while they grow."""

import os
import threading
from pathlib import Path

import pytest

from dynabarn.files import SyncAhead, write_atomically


def _open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="counts open files through /proc")
def test_sync_ahead_syncs_while_written_and_lets_go_of_the_file(tmp_path):
    path = tmp_path / "growing.bin"
    before = _open_fds()
    with open(path, "wb") as f:
        ahead = SyncAhead(path)
        assert _open_fds() == before + 2  # the writer's and the syncer's
        for i in range(50):
            f.write(bytes([i]) * 65536)
            f.flush()
            ahead.poke()
        ahead.close()
        assert not any(t.name == "sync-ahead" and t.is_alive() for t in threading.enumerate())
        assert _open_fds() == before + 1
        ahead.close()  # twice: nothing more
        ahead.poke()  # after the end: nothing
    data = path.read_bytes()
    assert len(data) == 50 * 65536 and data[-1] == 49 and data[65536] == 1


def test_write_atomically_replaces_whole_and_leaves_no_staging(tmp_path):
    path = tmp_path / "out.json"
    write_atomically(path, "old")
    write_atomically(path, b"new")
    assert path.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_sync_ahead_of_a_file_that_is_gone_does_nothing(tmp_path):
    ahead = SyncAhead(tmp_path / "renamed-away.part")
    ahead.poke()
    ahead.close()
    assert not any(t.name == "sync-ahead" and t.is_alive() for t in threading.enumerate())
