"""What the tests that stop a running ``senbench`` command share: start it as from a
terminal, wait until its cells have written result files, and stop it as Ctrl-C or a batch
scheduler would."""

import os
import signal
import subprocess
import time

import psutil
import pytest


def start_as_from_a_terminal(command, env):
    """The command in a process group of its own, SIGINT handled as usual (a shell's
    background job, CI's say, starts with SIGINT ignored)."""
    return subprocess.Popen(command, env=env, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_until(found, process, timeout, what):
    """``found()``'s first truthy value, polled; the process must not end first."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        if result := found():
            return result
        assert process.poll() is None, process.communicate()
        time.sleep(0.02)
    pytest.fail(f"{what} after {timeout} s")


def wait_for_files(directory, count, process, timeout=90):
    """Until ``directory`` holds ``count`` result files; the process must not end first."""
    wait_until(lambda: len(list(directory.glob("*.parquet"))) >= count, process, timeout,
               f"no {count} result files")


def stop(process, how):
    """``ctrl-c``: SIGINT to the foreground group, as a terminal sends it; ``sigterm``: to the
    command only, as a batch scheduler sends it."""
    if how == "ctrl-c":
        os.killpg(process.pid, signal.SIGINT)
    else:
        process.terminate()


def wait_for_fork_server(process, timeout=30):
    """The command's multiprocessing fork server, once it has been started."""

    def server():
        for child in psutil.Process(process.pid).children(recursive=True):
            try:
                if "multiprocessing.forkserver" in " ".join(child.cmdline()):
                    return child
            except psutil.Error:
                continue
        return None

    return wait_until(server, process, timeout, "no fork server")
