"""`--scheduler ADDRESS` / ``scheduler="tcp://..."`` pointing at something that is not a Dask scheduler ends in a
typed error naming the address within the stated bound (``mocapviz.parallel.CONNECT_TIMEOUT``, 10 s), never a
hang or an untyped traceback: the reproducers of issue 37 (``round3/scheduler/``: a peer that accepts and never
answers, an HTTP 426 answer) and ``python -m http.server``, each a real process on a free loopback port. A real
scheduler still serves, and a Dask worker's address or a scheduler without workers is refused by name."""
from __future__ import annotations

import logging
import os
import socket
import subprocess
import sys
import time

import pytest

distributed = pytest.importorskip("distributed")

from browser_helpers import free_port  # noqa: E402

from mocapviz import parallel  # noqa: E402
from mocapviz.errors import ClusterError, MocapvizError, SchedulerError  # noqa: E402

SERVERS = ["silent", "http.server", "http426"]
CLI_BOUND = parallel.CONNECT_TIMEOUT + 15.0  # the command: start-up (imports, opening the database) + the timeout


def _listening(port: int, proc: subprocess.Popen) -> None:
    """Wait (at most 10 s) until something accepts on 127.0.0.1:port."""
    for _ in range(200):
        assert proc.poll() is None, f"the server on port {port} ended with {proc.returncode}"
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise AssertionError(f"nothing listens on 127.0.0.1:{port} after 10 s")


@pytest.fixture(scope="module")
def fake_schedulers(round3):
    """{name: tcp address} of the three servers that are not Dask schedulers, each a process of its own on a free
    loopback port; stopped at the end."""
    commands = {"silent": [str(round3 / "scheduler" / "silent_server.py")],
                "http426": [str(round3 / "scheduler" / "http426_server.py")],
                "http.server": ["-m", "http.server", "--bind", "127.0.0.1"]}  # fmt: skip
    procs, addresses = [], {}
    try:
        for name in SERVERS:
            port = free_port()
            procs.append(subprocess.Popen([sys.executable, *commands[name], str(port)], stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL))  # fmt: skip
            _listening(port, procs[-1])
            addresses[name] = f"tcp://127.0.0.1:{port}"
        yield addresses
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("name", SERVERS)
def test_dask_client_refuses_what_is_not_a_scheduler_within_its_timeout(fake_schedulers, name):
    address = fake_schedulers[name]
    t0 = time.monotonic()
    with pytest.raises(SchedulerError, match=f"^cannot reach dask scheduler at {address}: ") as caught:
        with parallel.dask_client(address, timeout=2.0):
            pytest.fail("connected to a server that is not a Dask scheduler")
    took = time.monotonic() - t0
    assert took < 2.0 + 1.5, f"{name}: {took:.1f} s"
    assert isinstance(caught.value, ClusterError) and isinstance(caught.value, OSError)  # (callers caught OSError)
    assert isinstance(caught.value, MocapvizError) and len(str(caught.value)) < 300
    if name == "http426":  # answers at once: no need to wait for the timeout
        assert took < 1.0 and "does not speak the Dask protocol" in str(caught.value)
    else:
        assert "within 2 s" in str(caught.value)


@pytest.mark.slow
def test_the_cli_ends_with_the_typed_error_within_the_stated_bound(fake_schedulers, sample_db):
    """The commands of the issue, on each server (the three at once: they mostly wait): exit 1 with one line naming
    the address, well within CONNECT_TIMEOUT + start-up."""
    commands = {"silent": ["query", "--example", "7", "--features", "rknee_bent,lknee_bent"],
                "http.server": ["query", "--example", "7", "--features", "rknee_bent,lknee_bent"],
                "http426": ["find", "kick_right"]}  # fmt: skip
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    t0 = time.monotonic()
    procs = {name: subprocess.Popen([sys.executable, "-m", "mocapviz.cli", commands[name][0], str(sample_db.path),
                                     *commands[name][1:], "--scheduler", fake_schedulers[name]],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
             for name in SERVERS}  # fmt: skip
    try:
        for name, proc in procs.items():
            out, err = proc.communicate(timeout=CLI_BOUND + 30)
            took = time.monotonic() - t0
            assert proc.returncode == 1, (name, out, err)
            assert took < CLI_BOUND, f"{name}: {took:.1f} s"
            assert err.strip().splitlines() == [err.strip()], err  # one line, no traceback
            assert err.startswith(f"mocapviz: error: cannot reach dask scheduler at {fake_schedulers[name]}: "), err
    finally:
        for proc in procs.values():
            proc.kill()
            proc.wait()


@pytest.fixture(scope="module")
def cluster():
    """A real scheduler with one worker thread, in this process (cheap), and its worker's address."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as lc:  # fmt: skip
        yield lc


def _add(a: int, b: int) -> int:
    return a + b


def test_a_real_scheduler_by_address_still_serves(cluster):
    t0 = time.monotonic()
    with parallel.dask_client(cluster.scheduler_address) as client:
        assert time.monotonic() - t0 < 5 and client.submit(_add, 2, 3).result(timeout=30) == 5
        assert list(parallel.map_ordered(abs, [-3, 1, -2], client=client)) == [3, 1, 2]
    assert cluster.status.name == "running"  # disconnected; the cluster keeps running


def test_a_worker_address_and_a_scheduler_without_workers_are_refused_by_name(cluster):
    worker = next(iter(cluster.scheduler_info["workers"]))
    with pytest.raises(SchedulerError, match=f"at {worker}: what answers there is a Dask Worker, not a scheduler"):
        with parallel.dask_client(worker, timeout=2.0):
            pass
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as empty:  # fmt: skip
        t0 = time.monotonic()
        with pytest.raises(SchedulerError, match=f"at {empty.scheduler_address}: it has no worker"):
            with parallel.dask_client(empty.scheduler_address, timeout=1.0):
                pass
        assert time.monotonic() - t0 < 2.5
