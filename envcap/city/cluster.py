"""A Dask cluster for a city bake with every call bounded: connect to a scheduler or start a
``LocalCluster``, run calls on it under a timeout, shut it down.

Why a loop of its own (issue 20): Dask's synchronous client waits without limit in places: a
peer that accepts the connection and never speaks hangs it forever (the handshake is read with
no timeout), whatever ``Client(timeout=...)`` says.  A :class:`ClusterSession` runs an asyncio
loop in one daemon thread and uses Dask's asynchronous API there; the calling thread waits for
each call at most its timeout (:meth:`ClusterSession.call`) and cancels it past that.  The main
thread never blocks inside Dask, so SIGINT / SIGTERM reach it at once, and :meth:`close` shuts
the cluster down: the ``LocalCluster``'s worker processes are stopped (killed, if they do not
stop in time), and a worker process whose client dies unannounced (SIGKILL) exits by itself
(Dask's nanny pipe).  Local worker processes are started while this process ignores SIGINT
(the few milliseconds until they exist), so they ignore it for life: the Ctrl-C a terminal sends
to the whole process group acts on the client only, which stops them, instead of making each
worker print a ``KeyboardInterrupt`` traceback.

Before any Dask call, an address is checked (:func:`check_address`: scheme, host, port 1-65535)
and, for TCP, a plain connection is tried (:func:`_reachable`): an empty address, port 99999 or a
closed port fail at once, naming the address, instead of Dask's 30 s of retries.  A peer that is
not a Dask scheduler (silent, garbage, another protocol) fails within the timeout.  A scheduler
without workers is refused after the timeout (a bake would wait forever).

Failures are :class:`ClusterError` (a ``RuntimeError``): one line saying what failed, where, and
what to do; the CLI prints it as ``envcap: error: ...`` and exits 2.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import math
import multiprocessing
import os
import signal
import socket
import threading
import time
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar

import distributed

T = TypeVar("T")

DEFAULT_TIMEOUT_S = 10.0
"""Seconds to wait for any answer of a Dask scheduler (``--cluster-timeout``)."""
TCP_SCHEMES = ("tcp", "tls", "ws", "wss")
SCHEMES = (*TCP_SCHEMES, "inproc")
TRACKER_WARNING = "ignore::UserWarning:multiprocessing.resource_tracker"


class ClusterError(RuntimeError):
    """A Dask cluster failed (unreachable, not a scheduler, no workers, gone mid-bake); one line."""


def one_line(exc: BaseException) -> str:
    """``Type: message`` of ``exc`` on one line (Dask messages may span lines)."""
    text = " ".join(str(exc).split())
    name = type(exc).__name__
    name = f"{type(exc).__module__}.{name}" if name.islower() else name      # struct.error, not "error"
    return f"{name}: {text}" if text else name


def check_timeout(timeout_s: float) -> float:
    """``timeout_s`` if it is a finite number of seconds in (0, 3600], else ``ValueError``."""
    if not (isinstance(timeout_s, (int, float)) and math.isfinite(timeout_s) and 0 < timeout_s <= 3600):
        raise ValueError(f"--cluster-timeout must be a number of seconds in (0, 3600], got {timeout_s!r}")
    return float(timeout_s)


def check_address(address: str) -> str:
    """The scheduler ``address`` normalized (``tcp://`` added when it has no scheme), or
    ``ValueError`` in one line: empty, unknown scheme, no host, port outside 1-65535."""
    text = address.strip() if isinstance(address, str) else ""
    if not text:
        raise ValueError(f"--scheduler needs an address such as tcp://host:8786, got {address!r}")
    scheme, sep, loc = text.rpartition("://")
    scheme = scheme.lower() if sep else "tcp"
    if scheme not in SCHEMES:
        raise ValueError(f"--scheduler {address!r}: unknown scheme {scheme!r} (known: {', '.join(SCHEMES)})")
    if scheme in TCP_SCHEMES:
        host, port = _host_port(address, loc)
        loc = f"[{host}]:{port}" if ":" in host else f"{host}:{port}"
    return f"{scheme}://{loc}"


def _host_port(address: str, loc: str) -> tuple[str, int]:
    if loc.startswith("["):
        host, _, tail = loc[1:].partition("]")
        port_text = tail[1:] if tail.startswith(":") else ""
    else:
        host, _, port_text = loc.rpartition(":")
    if not host or ":" in host and not loc.startswith("[") or "/" in host:
        raise ValueError(f"--scheduler {address!r}: expected HOST:PORT after the scheme (e.g. tcp://127.0.0.1:8786)")
    if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise ValueError(f"--scheduler {address!r}: the port must be a number in 1-65535, got {port_text!r}")
    return host, int(port_text)


def _reachable(address: str, timeout_s: float) -> None:
    """A plain TCP connection to ``address`` (normalized): ``ClusterError`` at once when it is
    refused or the host is unknown, after ``timeout_s`` when nothing answers."""
    scheme, _, loc = address.partition("://")
    if scheme not in TCP_SCHEMES:
        return
    host, port = _host_port(address, loc)
    try:
        socket.create_connection((host, port), timeout=timeout_s).close()
    except ConnectionRefusedError:
        raise ClusterError(f"no Dask scheduler at {address}: connection refused (start one there: "
                           f"dask scheduler --port {port})") from None
    except socket.gaierror as exc:
        raise ClusterError(f"--scheduler {address}: unknown host {host!r} ({exc.strerror})") from None
    except TimeoutError:
        raise ClusterError(f"no Dask scheduler at {address}: no answer in {timeout_s:g} s (--cluster-timeout)") from None
    except OSError as exc:
        raise ClusterError(f"no Dask scheduler at {address}: {exc.strerror or one_line(exc)}") from None


def _ignoring_sigint() -> Any:
    """Ignore SIGINT in this process (main thread only; else None) and return the handler to put
    back.  A process started meanwhile inherits the ignored SIGINT and keeps it for life."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, signal.SIG_IGN)


def _restore_sigint(previous: Any) -> None:
    if previous is not None:
        signal.signal(signal.SIGINT, previous)


def _ignore(loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
    """The session loop's exception handler: nothing (failures reach the caller as ClusterError)."""


def _silence_dask_logs() -> dict[str, int]:
    """Raise every ``distributed`` logger (Dask's config gives some their own level) to CRITICAL;
    return the levels to put back."""
    names = ["distributed", *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]
    old = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL)
    return old


class ClusterSession:
    """A Dask client (and, for :meth:`start_local`, its ``LocalCluster``) on an event loop of its
    own thread; every call bounded (see the module docstring).  ``timeout_s``: the longest wait
    for any answer of the scheduler.  Use as a context manager, or call :meth:`close`."""

    def __init__(self, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        self.timeout_s = check_timeout(timeout_s)
        self.address = ""
        self.client: Any = None
        self.cluster: Any = None
        self._children: set[int] = set()
        self._log_levels = _silence_dask_logs()  # Dask's own lines (reconnects, shutdown): ours to say, in one
        self._loop = asyncio.new_event_loop()
        self._loop.set_exception_handler(_ignore)  # tasks of a cancelled start or a lost scheduler: said by us
        self._thread = threading.Thread(target=self._loop.run_forever, name="envcap-dask", daemon=True)
        self._thread.start()

    def __enter__(self) -> "ClusterSession":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self, make: Callable[[], Awaitable[T]]) -> "concurrent.futures.Future[T]":
        """Start ``make()`` on the session's loop; wait for it with :meth:`result`."""
        async def run() -> T:
            return await make()

        return asyncio.run_coroutine_threadsafe(run(), self._loop)

    def result(self, fut: "concurrent.futures.Future[T]", what: str, timeout_s: float | None = None) -> T:
        """Wait at most ``timeout_s`` (default: the session's) for ``fut``; past it the call is
        cancelled.  Any failure is a :class:`ClusterError` naming ``what``
        (``KeyboardInterrupt`` and other ``BaseException`` cancel the call and pass)."""
        wait = self.timeout_s if timeout_s is None else timeout_s
        try:
            return fut.result(timeout=wait)
        except concurrent.futures.TimeoutError:
            fut.cancel()
            raise ClusterError(f"{what}: no answer in {wait:g} s (--cluster-timeout)") from None
        except concurrent.futures.CancelledError:
            raise ClusterError(f"{what}: cancelled (the cluster went away)") from None
        except ClusterError:
            raise
        except Exception as exc:
            raise ClusterError(f"{what}: {one_line(exc)}") from None
        except BaseException:
            fut.cancel()
            raise

    def call(self, make: Callable[[], Awaitable[T]], what: str, timeout_s: float | None = None) -> T:
        """:meth:`start` then :meth:`result`: run ``make()`` on the loop, bounded."""
        return self.result(self.start(make), what, timeout_s)

    def connect(self, address: str) -> dict[str, Any]:
        """Connect to the scheduler at ``address`` and wait (at most the timeout) for a worker;
        return the scheduler's identity (``workers``: address -> info)."""
        self.address = check_address(address)
        _reachable(self.address, self.timeout_s)
        where = f"the Dask scheduler at {self.address}"

        async def connect() -> dict[str, Any]:
            self.client = distributed.Client(self.address, asynchronous=True, timeout=self.timeout_s,
                                             set_as_default=False)
            await self.client
            return await self.client.scheduler.identity()

        info = self.call(connect, f"connecting to {where} (is it a Dask scheduler?)")
        if not isinstance(info, dict) or info.get("type") != "Scheduler":
            raise ClusterError(f"{self.address} answers, but not as a Dask scheduler ({str(info)[:60]!r})")
        if not info.get("workers"):
            try:
                self.call(lambda: self.client.wait_for_workers(1, timeout=self.timeout_s), "waiting for a worker",
                          self.timeout_s * 2)
            except ClusterError:
                raise ClusterError(f"{where} has no workers (none joined in {self.timeout_s:g} s): start one with "
                                   f"dask worker {self.address}") from None
            info = self.identity()
        return info

    def start_local(self, workers: int, resources: dict[str, float] | None = None) -> None:
        """Start a ``LocalCluster`` of ``workers`` processes (one thread each) and connect to it;
        the wait grows with the count (process starts under load: ~1-5 s each)."""
        before = {p.pid for p in multiprocessing.active_children()}

        async def start() -> None:
            self.cluster = distributed.LocalCluster(   # held before it starts: close() stops a half-started one
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},   # no dashboard; its HTTP port: any free one
                resources=resources, silence_logs=logging.CRITICAL, asynchronous=True)
            await self.cluster
            self.client = distributed.Client(self.cluster, asynchronous=True, set_as_default=False)
            await self.client

        # multiprocessing's resource tracker (started with the first worker) would print a warning
        # about the semaphores of workers stopped mid-bake, after our one line; it removes them anyway
        old = os.environ.get("PYTHONWARNINGS")
        os.environ["PYTHONWARNINGS"] = ",".join(filter(None, [old, TRACKER_WARNING]))
        spawning = _ignoring_sigint()
        try:
            fut = self.start(start)
            while spawning is not None and not fut.done():       # until every worker process exists
                if len({p.pid for p in multiprocessing.active_children()} - before) >= workers:
                    break
                time.sleep(0.01)
            _restore_sigint(spawning)
            spawning = None
            self.result(fut, f"starting {workers} local Dask worker(s)", max(60.0, self.timeout_s) + 10.0 * workers)
        finally:
            _restore_sigint(spawning)
            self._children = {p.pid for p in multiprocessing.active_children()} - before
            if old is None:
                os.environ.pop("PYTHONWARNINGS", None)
            else:
                os.environ["PYTHONWARNINGS"] = old
        self.address = str(self.cluster.scheduler_address)

    @property
    def where(self) -> str:
        """The cluster in words, for messages."""
        return "the local Dask cluster" if self.cluster is not None else f"the Dask scheduler at {self.address}"

    def identity(self) -> dict[str, Any]:
        """The scheduler's identity now (its ``workers``), within the timeout."""
        return self.call(lambda: self.client.scheduler.identity(), f"asking {self.where}")

    def close(self) -> None:
        """Close the client and the ``LocalCluster`` (each within the timeout; worker processes
        that outlive it are killed), then stop the loop.  Safe to call twice."""
        if self._thread.is_alive():
            async def shut() -> None:
                try:
                    if self.client is not None:
                        await asyncio.wait_for(self.client.close(), self.timeout_s)
                    if self.cluster is not None:
                        await asyncio.wait_for(self.cluster.close(), max(self.timeout_s, 10.0))
                finally:
                    rest = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
                    for t in rest:
                        t.cancel()
                    if rest:
                        await asyncio.wait(rest, timeout=self.timeout_s)

            try:
                self.call(shut, "closing the Dask cluster", 2 * max(self.timeout_s, 10.0) + 1)
            except ClusterError:
                pass
            finally:
                self._kill_children()
                self._loop.call_soon_threadsafe(self._loop.stop)
                self._thread.join(self.timeout_s)
                if not self._thread.is_alive():
                    self._loop.close()
                self.client = self.cluster = None
                for name, level in self._log_levels.items():
                    logging.getLogger(name).setLevel(level)
                self._log_levels = {}

    def _kill_children(self) -> None:
        for p in multiprocessing.active_children():
            if p.pid in self._children:
                p.kill()
                p.join(5)
