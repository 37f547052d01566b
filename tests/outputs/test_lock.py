"""One writer per output: the lock refuses a second writer at once and leaves no file behind."""

import os
import signal
import threading
import time

import pytest

from envcap.outputs import OutputBusy, claim_output_dir
from envcap.outputs.deferred_signals import deferred_signals
from envcap.outputs.lock import OutputLock, lock_path


def test_a_second_claim_fails_at_once_and_the_lock_file_goes_away(tmp_path):
    final = tmp_path / "set"
    with claim_output_dir(final):
        assert lock_path(final).read_text().strip() == str(os.getpid())
        with pytest.raises(OutputBusy, match=f"process {os.getpid()}"):
            with claim_output_dir(final):
                pass
    assert list(tmp_path.iterdir()) == []
    with claim_output_dir(final):  # free again
        pass


def test_a_lock_file_left_by_a_killed_run_is_taken_over(tmp_path):
    final = tmp_path / "set"
    lock_path(final).write_text("99999\n")  # no process holds a lock on it
    lock = OutputLock(final)
    assert lock.held and lock_path(final).read_text().strip() == str(os.getpid())
    lock.release()
    assert not lock.held and list(tmp_path.iterdir()) == []


def test_sigterm_waits_until_the_deferred_block_ends():
    """Also with other threads in the process (as with OpenGL or BLAS threads): the kernel may
    hand the signal to any of them, the deferral must hold all the same."""
    seen = []
    stop = threading.Event()
    others = [threading.Thread(target=stop.wait) for _ in range(4)]

    def handler(signum, frame):
        seen.append(signum)

    previous = signal.signal(signal.SIGTERM, handler)
    for t in others:
        t.start()
    try:
        with deferred_signals():
            for _ in range(20):
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.001)
            assert seen == []  # recorded, not delivered
        assert seen == [signal.SIGTERM]  # delivered once, right after the block
    finally:
        stop.set()
        for t in others:
            t.join()
        signal.signal(signal.SIGTERM, previous)


def test_ctrl_c_during_the_deferred_block_is_raised_after_it():
    done = []
    with pytest.raises(KeyboardInterrupt), deferred_signals():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)
        done.append("block finished")
    assert done == ["block finished"]
