"""The Ray backend: :class:`RayEvaluator`, its actors, and how the jobs reach them.

The driver ships the task's code through Ray's runtime environment
(:mod:`skillcompose.evolve.ray_env`), starts one actor per CPU of the cluster, and sends the
jobs in chunks, over a direct connection to each actor (:mod:`skillcompose.evolve.channel`)
or through Ray's calls; :class:`_Generation` schedules one generation's chunks.
"""

from __future__ import annotations

import contextlib
import math
import secrets
import time
import warnings
from collections.abc import Iterable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any, cast

from skillcompose.errors import one_line
from skillcompose.task import Task, TaskRef

from .channel import HANDSHAKE_S, JobServer, connect, messages
from .errors import EvolutionError
from .evaluation import (
    LOST,
    TIMED_OUT,
    EvalLimits,
    Faults,
    Guard,
    Job,
    _pack,
    _Recycler,
    _unpack,
    evaluate_job,
)
from .genome import GenomeCompiler, SkillSet
from .ray_env import ray_runtime_env

__all__ = ["RayEvaluator"]

_MIN_CHUNK_S = 0.08
"""The least work [s] in one call to a Ray actor once jobs have been timed. On a local
cluster a call costs about 1.2 ms of the driver's CPU (taken from the workers when they
share its cores) and, when it is not queued behind a running one, about 2 ms of an idle
actor: some 3 ms in all, so 80 ms keeps a call under 4 % of its work. A generation with
less than this per actor is split evenly, one call each (docs/results/search.md, "Notes
from the evaluator's measurements", has what the floor was chosen on)."""


class _Unreachable(EvolutionError):
    """A Ray actor lives, but the driver cannot connect to it for its jobs."""


class _Actor:
    """A Ray actor of a :class:`RayEvaluator`, the node it runs on, and its calls in flight
    (oldest first: the first one is running, the others wait behind it)."""

    def __init__(self, handle: Any, node: str) -> None:
        self.handle = handle
        self.node = node
        self.calls: list[tuple[Any, int, list[Job], bool]] = []  # ref, position, jobs, alone
        self.conn: Connection | None = None  # the direct connection its jobs take, if any
        self.watch: Any = None  # the ref of its serving loop, which ends when it dies
        self.since = 0.0  # when its first call in flight started (roughly: sent or freed)
        self.retiring = False  # served its jobs or memory: replaced once its calls are done


class RayEvaluator:
    """Ray actors, each holding the task built once from its module and settings.

    Needs the optional extra: ``pip install skillcompose[ray]``. Connects to the cluster at
    ``RAY_ADDRESS`` when it is set, else starts a local one (without a dashboard; its
    servers listen on every interface, which Ray offers no setting to change), and ships
    the task's code to the workers through Ray's runtime environment
    (:func:`ray_runtime_env`; pass ``runtime_env`` to give your own), and disconnects on
    :meth:`close`. When Ray is already initialised, the caller's connection and runtime
    environment stand.

    Each actor takes one CPU of the cluster (``workers``: by default every CPU), spread
    over the nodes. Jobs go out in batches of one chunk per actor (factoring: each chunk a
    ``1 / chunks_per_worker`` share of what is left per actor, so large first and small
    last, but none under ``_MIN_CHUNK_S`` of work once a generation has timed the jobs,
    except that what is left is split evenly when it is less) to whichever actor is free,
    every actor given a first chunk before any a second, each holding at most two (one
    near the end), so a slow or busy node simply does less.
    ``nodes`` gives, for the last call, the node each job was evaluated on. With ``groups``
    set to k > 1 (islands: the population in k equal runs), group i's jobs go to the actors
    of the i-th node (mod the number of nodes) first, and to others only when those have
    nothing left (which runs where never changes a result).

    An actor that dies (its job crashed it, or its node went down) is replaced, and the
    jobs of the chunk it was running are run again one by one; only a job that kills the
    actor it runs on alone, twice, scores worst (``lost``): so a node lost in the middle of
    a run costs the run no result. An actor that cannot be placed (no free CPU left) is
    waited for while the others go on. With a wall-clock limit, an actor whose chunk
    overruns what its jobs' limits allow is killed and that chunk run again job by job,
    each job given the limit (a job that overruns it alone scores worst as a time-out).
    Actors are replaced after ``max_jobs`` jobs or ``max_growth_mb`` of memory growth.

    With ``direct`` (the default) the chunks and their results go over a connection of
    :mod:`skillcompose.evolve.channel` from the driver to each actor, not through Ray's calls, which
    cost a tenth of a small generation; when the driver cannot connect to the first
    actors (a firewall that opens Ray's ports only, say), it warns once and uses Ray's
    calls (``direct=False``).
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None,
        chunks_per_worker: int = 2, limits: EvalLimits | None = None,
        runtime_env: dict[str, Any] | None = None, start_timeout: float = 120.0,
        direct: bool = True,
    ) -> None:
        try:
            import ray
        except ImportError as exc:
            raise EvolutionError(
                "backend 'ray' needs Ray: pip install skillcompose[ray] "
                "(or use --backend process)"
            ) from exc
        env, self._ref = ray_runtime_env(task)
        self._ray: Any = ray
        self._owns_ray = not ray.is_initialized()  # then closed with this evaluator
        if self._owns_ray:
            ray.init(ignore_reinit_error=True, log_to_driver=False, include_dashboard=False,
                     runtime_env=env if runtime_env is None else runtime_env)
        self.task = task
        self.workers = workers or int(ray.cluster_resources().get("CPU", 1)) or 1
        self.chunks_per_worker = chunks_per_worker
        self.limits = limits or EvalLimits()
        self.start_timeout = start_timeout
        self._actor_cls = ray.remote(num_cpus=1, scheduling_strategy="SPREAD")(_RayWorker)
        self._shape = skills.shape
        self._actors: list[_Actor] = []
        self._starting: dict[Any, Any] = {}  # ready ref -> actor handle
        self.lost = 0
        self.faults = Faults()
        self.nodes: list[str] = []
        self.groups = 1
        self._job_s: float | None = None  # seconds per job, as the last generation ran
        self.direct = direct
        self._key = secrets.token_bytes(32)  # proves the driver to its actors, and back
        try:  # the driver's node, where actors listen on 127.0.0.1 only
            self._home = str(ray.get_runtime_context().get_node_id())
        except Exception:  # a driver on no node (Ray Client): every actor on its address
            self._home = ""
        try:
            try:
                self._start_all()
            except _Unreachable as exc:
                warnings.warn(f"{exc}; the jobs go through Ray's calls instead, slower",
                              RuntimeWarning, stacklevel=2)
                self.close(keep_ray=True)
                self.direct = False
                self._start_all()
        except BaseException:
            self.close()
            raise

    def _start_all(self) -> None:
        for _ in range(self.workers):
            self._start_actor()
        self._await_actors(wait_all=True)

    def _start_actor(self) -> None:
        handle: Any = self._actor_cls.remote(
            self._ref, self._shape, self.limits, self._key if self.direct else None,
            self._home)
        self._starting[handle.ready.remote()] = handle

    def _await_actors(self, wait_all: bool = False, timeout: float = 0.0) -> None:
        """Take in the actors that have started: all of them, up to ``start_timeout``, when
        ``wait_all``; else the first within ``timeout`` (0: those there now). Having waited,
        fail when there is none."""
        ray = self._ray
        waits = wait_all or timeout > 0
        deadline = time.monotonic() + (self.start_timeout if wait_all else timeout)
        while self._starting:
            left = max(0.0, deadline - time.monotonic())
            done, _ = ray.wait(list(self._starting), num_returns=1, timeout=left)
            if not done:
                break
            handle = self._starting.pop(done[0])
            try:
                node, address = ray.get(done[0])
            except ray.exceptions.RuntimeEnvSetupError as exc:
                self._discard_starting()
                raise EvolutionError(
                    f"Ray could not set up the workers' runtime environment for task "
                    f"{self.task.name}: {str(exc).strip().splitlines()[-1]}"
                ) from exc
            except Exception as exc:
                self._discard_starting()
                raise EvolutionError(
                    f"a Ray actor could not build task {self.task.name}: "
                    f"{str(exc).strip()[-800:]}"
                ) from exc
            actor = _Actor(handle, node)
            if address is not None and not self._connect(actor, tuple(address)):
                self._start_actor()  # it died on the way: another
                continue
            self._actors.append(actor)
            if not wait_all:
                deadline = time.monotonic()  # take what has started, without waiting more
        if not self._actors and waits:
            self._discard_starting()
            raise EvolutionError(
                f"no Ray actor started in {self.start_timeout:g} s: the cluster has no free "
                "CPU (see `ray status`), or use fewer --workers"
            )

    def _connect(self, actor: _Actor, address: tuple[str, int]) -> bool:
        """Start ``actor``'s serving loop and connect to it: False if it died meanwhile;
        raises :class:`_Unreachable` when it lives but cannot be reached."""
        ray = self._ray
        actor.watch = actor.handle.serve.remote()
        try:
            actor.conn = connect(address, self._key)
            return True
        except Exception as exc:
            done, _ = ray.wait([actor.watch], timeout=1.0)
            with contextlib.suppress(Exception):
                ray.kill(actor.handle)
            if done:
                return False
            self._discard_starting()
            raise _Unreachable(
                f"the driver could not connect to a Ray actor at {address[0]}:{address[1]} for "
                f"its jobs ({one_line(str(exc)) or type(exc).__name__}): open TCP from the "
                "driver to the nodes' ephemeral ports, or use RayEvaluator(direct=False)"
            ) from exc

    def _discard_starting(self) -> None:
        for handle in self._starting.values():
            with contextlib.suppress(Exception):
                self._ray.kill(handle)
        self._starting = {}

    def _drop(self, actor: _Actor) -> None:
        """Take ``actor`` out of the pool (killing it, if it lives) and start a replacement."""
        self._kill(actor)
        self._actors.remove(actor)
        self._start_actor()

    def _kill(self, actor: _Actor) -> None:
        if actor.conn is not None:
            actor.conn.close()
            actor.conn = None
        with contextlib.suppress(Exception):  # an actor that died already
            self._ray.kill(actor.handle)

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        self.faults = Faults()
        self.nodes = []
        for actor in [a for a in self._actors if a.calls]:  # a generation ended by an
            self._drop(actor)  # exception (its jobs' breeding raised, Ctrl-C)
        # a generation handed over as it is bred (an iterator, with its expected size) goes
        # out as it comes, so the actors evaluate while the driver breeds the rest; islands
        # need the whole generation first, to cut it into runs at home on their nodes
        stream: Iterator[Job] | None = None
        whole: list[Job] = []
        if not isinstance(jobs, Sequence) and expected and self.groups <= 1:
            stream = iter(jobs)
        else:
            whole = list(jobs)
            if not whole:
                return []
        return _Generation(self, whole, stream, expected).run()

    def close(self, keep_ray: bool = False) -> None:
        for a in self._actors:
            self._kill(a)
        self._actors = []
        self._discard_starting()
        # its runtime environment was this task's: the next starts anew
        if self._owns_ray and not keep_ray:
            self._ray.shutdown()
            self._owns_ray = False


class _Generation:
    """One call of :meth:`RayEvaluator.evaluate`: the generation's jobs, where each one
    stands, and how their chunks go out to the evaluator's actors and come back.

    The jobs are cut in ``groups`` equal runs (islands), group k at home on the k-th node
    (mod their number): an actor takes from its own node's groups first, then from any.
    """

    def __init__(
        self, ev: RayEvaluator, jobs: list[Job], stream: Iterator[Job] | None,
        expected: int | None,
    ) -> None:
        self.ev = ev
        self.faults = ev.faults
        self.jobs = jobs
        self.stream = stream  # the jobs still to come, while they are bred
        n = self.n = len(jobs)
        self.out = [math.nan] * n
        self.codes = [0] * n
        self.nodes = [""] * n
        self.errors: list[tuple[int, str]] = []
        self.singles: list[int] = []  # positions to run alone, after their actor died
        self.crashed: dict[int, int] = {}  # position -> actors it killed running alone
        self.again: list[tuple[int, list[Job]]] = []  # chunks sent to an actor that died first
        self.per_job = ev.limits.kill_after
        self.tick = 1.0 if self.per_job is None else min(1.0, self.per_job / 4)
        homes = sorted({a.node for a in ev._actors})
        groups = self.groups = max(1, min(ev.groups, n))
        # per group: the next job and the end of its run; the node it is at home on; the
        # chunk size of its batch and the chunks left in that batch
        self.spans = [[k * n // groups, (k + 1) * n // groups] for k in range(groups)]
        self.home = [homes[k % len(homes)] if groups > 1 and homes else ""
                     for k in range(groups)]
        self.batches = [[0, 0] for _ in range(groups)]
        self.tail = self.least(n, ev.chunks_per_worker * max(1, len(ev._actors)))
        self.busy = [0.0, 0]  # seconds the actors spent on jobs, and jobs, this generation
        # while streaming: chunks of a quarter of each actor's share of the expected jobs
        # (an eighth of them on two actors; never under a tenth of the time floor once
        # timed), each actor holding two
        self.streamed = max(math.ceil((expected or 1) / (ev.chunks_per_worker * 2 * max(
            1, len(ev._actors)))), 1 if ev._job_s is None else
            math.ceil(_MIN_CHUNK_S / 10 / ev._job_s))
        self.watched = time.monotonic()  # when dead actors were last looked for

    def run(self) -> list[float]:
        """Send the chunks out and take their results in until every job has one; then
        count the generation's faults."""
        ev = self.ev
        self.feed_all()
        while True:
            if self.stream is not None:
                self.pull()
            ev._await_actors()
            self.feed_all()
            if not any(a.calls for a in ev._actors):
                if self.stream is None and all(a >= b for a, b in self.spans) \
                        and not self.singles and not self.again:
                    break
                if not ev._actors:  # every actor died: wait for a replacement
                    ev._await_actors(timeout=ev.start_timeout)
                continue
            # while jobs come, only what is back now: then on to take (breed) more
            timeout = 0.0 if self.stream is not None else self.tick
            if ev.direct:
                self.take_direct(timeout)
            else:
                self.take_calls(timeout)
            if self.per_job is not None:
                self.kill_overdue(self.per_job)
        return self.finish()

    def finish(self) -> list[float]:
        """Count the faults, time the jobs (for the next generation's chunks) and note
        where each ran; the fitnesses."""
        ev = self.ev
        for p, job in enumerate(self.jobs):
            self.faults.count(self.codes[p], job.trials)
        if self.errors:
            self.faults.first_error = min(self.errors)[1]
        if self.busy[1]:
            ev._job_s = self.busy[0] / self.busy[1]
        ev.nodes = self.nodes
        return self.out

    # -- sending ---------------------------------------------------------------------------
    def next_work(self, actor: _Actor) -> tuple[int, list[Job], bool] | None:
        """The next chunk for ``actor``: its first position, its jobs, and whether it is
        one job to run alone (after its actor died); None when there is none now."""
        ev, jobs = self.ev, self.jobs
        if self.singles:
            p = self.singles.pop(0)
            return p, [jobs[p]], True
        if self.again:
            return (*self.again.pop(0), False)
        spans, home, batches = self.spans, self.home, self.batches
        if self.stream is not None:  # chunks of a fixed size while the jobs come
            start, end = spans[0]
            if end - start < self.streamed:
                return None
            spans[0][0] = start + self.streamed
            return start, jobs[start:start + self.streamed], False
        groups, n = self.groups, self.n
        own = [k for k in range(groups) if home[k] in ("", actor.node)]
        for k in own + [k for k in range(groups) if k not in own]:
            start, end = spans[k]
            if start < end:
                workers = sum(a.node == home[k] for a in ev._actors) if home[k] else \
                    len(ev._actors)
                share = ev.chunks_per_worker * max(1, workers)
                left = end - start
                if batches[k][1] <= 0:  # a new batch: one chunk for each actor
                    batches[k] = [max(math.ceil(left / share), min(
                        self.least(end - k * n // groups, share),
                        math.ceil(left / max(1, workers)))), max(1, workers)]
                size = batches[k][0]
                batches[k][1] -= 1
                spans[k][0] = min(end, start + size)
                return start, jobs[start:spans[k][0]], False
        return None

    def least(self, jobs_in: int, share: int) -> int:
        """The smallest chunk of a run of ``jobs_in`` jobs cut in ``share`` shares: an
        eighth of a share, and (once a generation has timed the jobs) at least
        ``_MIN_CHUNK_S`` of work."""
        job_s = self.ev._job_s
        timed = 1 if job_s is None else math.ceil(_MIN_CHUNK_S / job_s)
        return max(1, jobs_in // (8 * share), timed)

    def pull(self) -> None:
        """Take a chunk's worth more jobs from the stream (bred meanwhile); at its end,
        the generation is whole and what is left goes out by factoring."""
        assert self.stream is not None
        for _ in range(self.streamed):
            job = next(self.stream, None)
            if job is None:
                self.stream = None
                break
            self.jobs.append(job)
            self.out.append(math.nan)
            self.codes.append(0)
            self.nodes.append("")
        self.n = len(self.jobs)
        self.spans[0][1] = self.n
        if self.stream is None:
            self.tail = self.least(self.n, self.ev.chunks_per_worker * max(
                1, len(self.ev._actors)))

    def feed(self, actor: _Actor, most: int = 2) -> None:
        """Give ``actor`` chunks until it holds ``most`` (fewer near the end)."""
        ev = self.ev
        # a second call waits behind the running one (hiding the round trip) only while
        # more than a chunk per actor is left: at the end of a generation a queued chunk
        # would keep its actor busy while another, free, has nothing to take
        while not actor.retiring and len(actor.calls) < min(most, (
                2 if self.stream is not None or sum(e - s for s, e in self.spans) >
                self.tail * len(ev._actors) else 1)):
            work = self.next_work(actor)
            if work is None:
                return
            p, chunk, alone = work
            if not actor.calls:
                actor.since = time.monotonic()
            if actor.conn is None:
                actor.calls.append(
                    (actor.handle.run.remote(_pack(chunk), p), p, chunk, alone))
                continue
            actor.calls.append((None, p, chunk, alone))
            try:
                actor.conn.send((_pack(chunk), p))
            except Exception:  # it died: what it had goes again
                self.died(actor, killed=False)
                return

    def feed_all(self) -> None:
        ev = self.ev
        for most in (1, 2):  # a first chunk to every actor before a second to any
            for actor in list(ev._actors):
                if actor in ev._actors:
                    self.feed(actor, most)

    # -- taking results back ---------------------------------------------------------------
    def record(self, actor: _Actor, p: int, result: Any) -> None:
        fitness, chunk_codes, error, worn, seconds = result
        self.busy[0] += seconds
        self.busy[1] += len(fitness)
        self.out[p:p + len(fitness)] = fitness
        self.codes[p:p + len(fitness)] = chunk_codes
        self.nodes[p:p + len(fitness)] = [actor.node] * len(fitness)
        if error is not None:
            self.errors.append(error)
        if worn and not actor.retiring:
            actor.retiring = True
            self.faults.recycled += 1

    def finished(self, actor: _Actor, result: Any, k: int = 0) -> None:
        _, p, _, _ = actor.calls.pop(k)
        actor.since = time.monotonic()
        self.record(actor, p, result)
        if actor.retiring and not actor.calls:
            self.ev._drop(actor)

    def take_direct(self, timeout: float) -> None:
        """Take the results that come back over the actors' connections within
        ``timeout``; when none came, look for actors Ray knows died without closing
        their connection (a node cut off)."""
        ev = self.ev
        conns = {a.conn: a for a in ev._actors if a.calls and a.conn is not None}
        ready = wait(list(conns), timeout)
        for conn in ready:
            actor = conns[cast(Connection, conn)]
            if actor not in ev._actors:
                continue
            try:
                result = actor.conn.recv() if actor.conn is not None else None
            except Exception:  # it died (its process, or its node)
                self.died(actor, killed=False)
                continue
            self.finished(actor, result)
        if ready or time.monotonic() - self.watched < self.tick:
            return
        self.watched = time.monotonic()
        watches = {a.watch: a for a in ev._actors if a.calls}
        if watches:
            gone, _ = ev._ray.wait(list(watches), num_returns=len(watches), timeout=0)
            for ref in gone:
                if watches[ref] in ev._actors:
                    self.died(watches[ref], killed=False)

    def take_calls(self, timeout: float) -> None:
        """Take the result of a Ray call that comes back within ``timeout``."""
        ev, ray = self.ev, self.ev._ray
        calls = {c[0]: a for a in ev._actors for c in a.calls}
        done, _ = ray.wait(list(calls), num_returns=1, timeout=timeout)
        for ref in done:
            actor = calls[ref]
            if actor not in ev._actors:  # already handled as dead in this round
                continue
            try:
                result = ray.get(ref)
            except Exception:  # the actor died (RayActorError), or its node did
                self.died(actor, killed=False)
                continue
            self.finished(actor, result,
                          next(i for i, c in enumerate(actor.calls) if c[0] == ref))

    # -- faults ----------------------------------------------------------------------------
    def kill_overdue(self, per_job: float) -> None:
        """Kill each actor whose running chunk overran what its jobs' limits allow."""
        ev = self.ev
        now = time.monotonic()
        for actor in list(ev._actors):
            if actor.calls and now - actor.since > len(actor.calls[0][2]) * per_job:
                with contextlib.suppress(Exception):
                    ev._ray.kill(actor.handle)
                self.died(actor, killed=True)

    def died(self, actor: _Actor, killed: bool) -> None:
        """The actor is gone (or ``killed`` by us for time): keep what it finished,
        run again what it had not."""
        ev = self.ev
        unfinished = []
        if actor.conn is not None:  # what it sent back before it went
            with contextlib.suppress(Exception):
                while actor.calls and actor.conn.poll(0):
                    result = actor.conn.recv()
                    self.record(actor, actor.calls.pop(0)[1], result)
        for ref, p, chunk, alone in actor.calls:
            try:
                if ref is None:
                    raise EOFError
                self.record(actor, p, ev._ray.get(ref, timeout=0))
            except Exception:
                unfinished.append((p, chunk, alone))
        actor.calls = []
        if not killed:
            self.faults.worker_deaths += 1
        for k, (p, chunk, alone) in enumerate(unfinished):
            if k:  # never started: as they were
                if alone:
                    self.singles.insert(0, p)
                else:
                    self.again.insert(0, (p, chunk))
            elif alone and killed:
                self.out[p], self.codes[p], self.nodes[p] = ev.task.worst, TIMED_OUT, actor.node
            elif alone and self.crashed.get(p, 0) >= 1:  # it killed a second actor alone
                self.out[p], self.codes[p], self.nodes[p] = ev.task.worst, LOST, actor.node
                ev.lost += 1
            elif alone:
                self.crashed[p] = self.crashed.get(p, 0) + 1
                self.singles.insert(0, p)
            else:
                self.singles[:0] = range(p, p + len(chunk))
        ev._drop(actor)


class _RayWorker:
    def __init__(
        self, ref: TaskRef, shape: tuple[tuple[str, ...], bool], limits: EvalLimits,
        key: bytes | None,
        home: str,
    ) -> None:
        self.task = ref.build()
        self.compiler = GenomeCompiler(self.task, SkillSet.from_task(self.task, *shape))
        self.guard = Guard(limits.time_limit).install()
        self.recycler = _Recycler(limits)
        self._key = key
        self._home = home  # the node of the evaluator
        self._jobs: JobServer | None = None

    def ready(self) -> tuple[str, tuple[str, int] | None]:
        """The id of the node this actor runs on, and, when the evaluator gave a key, the
        address where it takes its jobs (127.0.0.1 on the evaluator's own node)."""
        import ray

        node = str(ray.get_runtime_context().get_node_id())
        if self._key is None:
            return node, None
        host = "127.0.0.1" if node == self._home else ray.util.get_node_ip_address()
        self._jobs = JobServer(host, self._key)
        return node, self._jobs.address

    def serve(self) -> None:
        """Run the chunks that come over the evaluator's connection (each ``(packed, at)``
        as :meth:`run` takes them), sending back each one's results, until it closes.
        Runs on the actor's main thread, as Ray's calls do, so the time limit works."""
        assert self._jobs is not None, "ready() first"
        with self._jobs.accept(3 * HANDSHAKE_S) as conn:
            for packed, at in messages(conn):
                conn.send(self.run(packed, at))

    def run(
        self, packed: bytes, at: int
    ) -> tuple[list[float], list[int], tuple[int, str] | None, bool, float]:
        """Fitnesses, fault codes, the first exception (position, summary), whether this
        actor should now be replaced, and the seconds the jobs took, for the jobs
        ``packed`` by :func:`_pack` (one
        bytes argument: Ray passes it as it is, at a fraction of the cost of serialising
        the jobs' nested tuples itself)."""
        t0 = time.perf_counter()
        jobs = _unpack(packed)
        fitness: list[float] = []
        codes: list[int] = []
        first: tuple[int, str] | None = None
        for i, job in enumerate(jobs):
            f, code, error = evaluate_job(self.task, self.compiler, job, self.guard,
                                          first is None)
            fitness.append(f)
            codes.append(code)
            if error is not None and first is None:
                first = (at + i, error)
        return fitness, codes, first, self.recycler.worn(len(jobs)), time.perf_counter() - t0
