"""Running a whole network: slave workers (``up``), one master per link, the timeline, live status, the report.

``mlink-sim up`` = :func:`run_up` (starts the slave workers, then :func:`run_network`);
``mlink-sim master`` = :func:`run_network` against endpoints elsewhere.

Touches: the process's signal handlers (SIGINT, SIGTERM) while it runs, stdout (the status, the summary), stderr
(notices), the report file; everything else through the session.
"""

from __future__ import annotations

import asyncio
import dataclasses
import os
import secrets
import signal
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any


from ... import _accel
from ..._log import get_logger
from ...config import Config, TimelineStep, format_ns
from ...metrics import write_report
from ...scenario import CheckResult, Timeline, speed_scales
from ...scenario.expectations import timeline_warnings
from ..control.endpoint import ControlServer
from ..control.events import RunLog
from ..control.network import NetworkOps
from ..control.timeline import TimelineRunner, sleep_until
from ..present.status import LiveStatus, StatusInfo, WorstP99, render_lines
from ..present.trace import DEFAULT_INTERVAL_NS, TraceSampler
from ..timing.slack import Slack
from .session import EndpointError, NetworkSession
from .supervisor import resolve_workers
from .verdict import SIGNAL_EXIT, Verdict, print_summary
from .virtual_session import VirtualSession
from .webproc import WebProcess

__all__ = ["RunOptions", "RunOutcome", "SIGNAL_EXIT", "EndpointError", "run_up", "run_network", "cut_by_duration"]

log = get_logger("mlink_sim.network")


@dataclasses.dataclass
class RunOptions:
    """How a run behaves (command-line flags of ``up`` / ``master``)."""

    config_path: Path
    duration_ns: int | None = None  #: stop after this long (from the end of bring-up); None = the timeline's end
    report_path: Path | None = None  #: write the JSON report here (atomically)
    assertions: Sequence[Any] = ()  #: parsed --assert expressions
    status: bool = True  #: live status on stdout
    bringup_timeout_s: float = 10.0
    include_bringup: bool = False  #: False: the report's figures count from the end of bring-up
    #: worker processes of the slaves (up): a number, "auto" (one per station up to max(2, CPUs − 1) stations, else
    #: CPUs − 1 processes) or "station" (one process per station); see ``supervisor.resolve_workers``
    workers: int | str = "auto"
    state_dir: Path | None = None  #: EEPROM images of the slaves (up)
    run_dir: Path | None = None  #: worker logs (up); default a temporary directory
    restart_slaves: bool = True  #: restart a worker that died (up)
    log_json: bool = False  #: notices on stderr as JSON log lines (--log-json)
    #: "real" (slave processes, UDP, the wall clock) or "virtual" (one process, in-memory network, simulated time;
    #: the loop must be a ``vclock.VirtualEventLoop``), docs/virtual-time.md
    clock: str = "real"
    seed: int = 0  #: every random draw: the impairments' (docs/faults.md), the virtual network model's jitter
    realtime: bool = False  #: SCHED_FIFO, locked memory, the clock on a CPU of its own, where permitted (CLI: on)
    #: ``--cpus``: the CPUs of the network (the master on the highest, the workers on the rest), placed with or
    #: without *realtime*; None: the kernel's choice, or the real-time plan
    cpus: set[int] | None = None
    capture: Any = None  #: a started CaptureWriter recording every datagram of the masters (``--capture``)
    #: ``--control HOST:PORT``: answer the network's operations while running (aio/control, docs/control.md)
    control: tuple[str, int] | None = None
    #: ``--control-token``: the token every control request must carry (None: none; aio/control/token.py)
    control_token: str | None = None
    #: ``--trace FILE.csv``: each station's figures every ``trace_interval_ns`` and the actions (aio/present/trace.py)
    trace_path: Path | None = None
    trace_interval_ns: int = DEFAULT_INTERVAL_NS
    #: ``--report-html FILE``: the HTML report (metrics/html.py); without ``trace_path`` from a temporary trace
    report_html: Path | None = None
    #: ``--web [HOST:]PORT``: serve the page and the HTTP API here, in a process of its own (aio/run/webproc.py);
    #: without ``--control`` the run opens a control endpoint on 127.0.0.1 for it, with a token of its own
    web: tuple[str, int] | None = None
    #: ``--web-token``: the token every API request must carry (None: none)
    web_token: str | None = None


@dataclasses.dataclass
class RunOutcome:
    exit_code: int
    report: dict[str, Any]
    checks: list[CheckResult]
    problems: list[str]


async def run_up(config: Config, opts: RunOptions) -> RunOutcome:
    """Start the slave worker processes (``--workers``: one per station, or packed), then run the network against
    them."""
    return await _run(config, opts, None)


async def run_network(config: Config, endpoints: dict[int, tuple[str, int]], opts: RunOptions) -> RunOutcome:
    """Start one master per link against *endpoints* (slaves started elsewhere) and run the network."""
    return await _run(config, opts, endpoints)


async def _run(config: Config, opts: RunOptions, endpoints: dict[int, tuple[str, int]] | None) -> RunOutcome:
    """Bring the stations up, run the timeline with the live status until its end / --duration / a signal, then
    DISCONNECT, write the report, evaluate the assertions and print the summary.

    SIGINT / SIGTERM end the run in order (DISCONNECT, workers stopped, report written) with exit 130 / 143 and
    "interrupted" in the summary and in ``meta.interrupted``; the timeline steps that did not begin are listed as
    not run (``meta.not_run``).

    The phases, in order: the workers (:func:`_workers`), the session and its control endpoint (:func:`_open`),
    the bring-up (:func:`_bring_up`), the timeline with the live status (:func:`_timeline`), the report
    (:func:`_report`), the close (:func:`_close`, whatever happened before) and the verdict (:func:`_verdict`)."""
    run = _Run(config, opts, asyncio.get_running_loop())
    log.info("cores", mode=_accel.MODE, detail=_accel.REASON)  # compiled or pure (docs/performance.md)
    run.catch_signals()
    session_cls, workers = _workers(run, endpoints)
    length = opts.duration_ns if opts.duration_ns is not None else config.run_length_ns
    for line in timeline_warnings(config, str(opts.config_path)):  # docs/configuration.md
        _notice(opts, "check_beyond_settings", f"warning: {line}")
    cut = cut_by_duration(config, opts.duration_ns)
    if cut:
        _notice(opts, "steps_cut", f"warning: --duration {format_ns(opts.duration_ns or 0)} ends the run before "
                f"{len(cut)} timeline step(s), which will not run: {'; '.join(s.describe for s in cut)}")
    scales = speed_scales(config)  # now, not in the event loop once it keeps time
    run.status = LiveStatus() if opts.status else None
    timeline = Timeline(config)
    try:
        session = await _open(run, session_cls, endpoints, workers, scales)
        stopper = run.loop.create_task(run.stop.wait())
        await _bring_up(run, session, stopper)
        assert run.ops is not None
        run.ops.timeline = timeline
        runner = TimelineRunner(timeline, run.ops)
        capture = opts.capture
        if capture is not None:  # the timeline's actions (runs, writes, injected faults) as capture comments
            runner.note = lambda text: capture.note(int(run.loop.time() * 1e9), text)
        if not run.stop.is_set():
            await _timeline(run, session, runner, stopper, length)
        stopper.cancel()
        report = await _report(run, session, timeline)
    except BaseException:
        _drop_temporary_trace(run)
        raise
    finally:
        await _close(run)
    return _verdict(run, report, timeline, session)


@dataclasses.dataclass
class _Run:
    """What the phases of one run share: the loop, the stop a signal asks for, and what the close must release."""

    config: Config
    opts: RunOptions
    loop: asyncio.AbstractEventLoop
    stop: asyncio.Event = dataclasses.field(default_factory=asyncio.Event)
    caught: list[signal.Signals] = dataclasses.field(default_factory=list)  #: the signal that ended the run
    status: LiveStatus | None = None
    control: ControlServer | None = None
    ops: NetworkOps | None = None  #: the network's operations: the timeline's, and the control endpoint's
    session: NetworkSession | None = None
    sampler: TraceSampler | None = None  #: the trace (--trace, --report-html)
    trace_file: Path | None = None  #: where it is written: --trace's file, or a temporary one for --report-html
    web: WebProcess | None = None

    def catch_signals(self) -> None:
        """SIGINT / SIGTERM set :attr:`stop` (the first one is kept for the exit status); :func:`_close` removes
        the handlers."""
        for sig in SIGNAL_EXIT:
            self.loop.add_signal_handler(sig, self._on_signal, sig)

    def _on_signal(self, sig: signal.Signals) -> None:
        if not self.caught:
            self.caught.append(sig)
            log.info("signal", signal=sig.name)
        self.stop.set()


def _workers(run: _Run, endpoints: dict[int, tuple[str, int]] | None) -> tuple[type[NetworkSession], int | None]:
    """Which session runs the network and how many slave worker processes it starts: the virtual clock's session
    (no processes), none for ``mlink-sim master`` (*endpoints* given: the slaves run elsewhere), else the
    ``--workers`` choice, with a notice when "auto" packs the stations."""
    config, opts = run.config, run.opts
    if opts.clock == "virtual":
        return VirtualSession, None
    if endpoints is not None:
        return NetworkSession, None
    workers = resolve_workers(opts.workers, len(config.station))
    if opts.workers == "auto" and workers is not None:
        _notice(opts, "workers_packed", f"note: {len(config.station)} stations on {os.cpu_count() or 1} CPUs: "
                f"hosted in {workers} slave process(es), so the master's clock keeps a CPU (--workers station: "
                "one process per station; docs/performance.md)")
    return NetworkSession, workers


async def _open(run: _Run, session_cls: type[NetworkSession], endpoints: dict[int, tuple[str, int]] | None,
                workers: int | None, scales: dict[int, Any]) -> NetworkSession:
    """Open the session (the workers, one master per link), its operations and, with ``--control`` (or ``--web``),
    the control endpoint that serves them."""
    opts = run.opts
    session = run.session = await session_cls.open(
        run.config, opts.config_path, endpoints=endpoints, workers=workers, state_dir=opts.state_dir,
        run_dir=opts.run_dir, restart_slaves=opts.restart_slaves, realtime=opts.realtime, capture=opts.capture,
        seed=opts.seed, cpus=opts.cpus)
    if session.realtime_granted:
        granted = "; ".join(f"{p} {g}" for p, g in session.realtime_granted.items())
        _notice(opts, "realtime", f"realtime: {granted} (--no-realtime: none of it)" if opts.realtime
                else f"cpus: {granted}")
    if opts.trace_path is not None or opts.report_html is not None:
        run.sampler = _open_trace(run, session)
    masters = list(session.masters.values())
    events = RunLog(masters[0].now_ns)
    for master in masters:
        events.watch(master)
    run.ops = NetworkOps(session, events, opts.assertions, in_thread=opts.clock != "virtual", scales=scales)
    if opts.control is not None or opts.web is not None:
        # --web without --control: an endpoint on loopback for the web server only, with a token of its own
        token = opts.control_token if opts.control is not None else secrets.token_urlsafe(16)
        handlers = run.ops.handlers()
        run.control = ControlServer(run.sampler.recording(handlers) if run.sampler else handlers, "network",
                                    token=token)
        host, port = await run.control.start(*(opts.control or ("127.0.0.1", 0)))
        if opts.control is not None:
            _notice(opts, "control", f"control: {host}:{port} (mlink-sim status {host}:{port}; mlink-sim param "
                                     f"get|set {host}:{port} …; mlink-sim control {host}:{port} OP)")
        if opts.web is not None:
            run.web = WebProcess(opts.web, opts.web_token, log_json=opts.log_json)
            url = await run.web.start((host, port), token)
            _notice(opts, "web", f"web: {url}" + (" (the page: this address with #token=TOKEN; docs/web.md)"
                                                   if opts.web_token else ""))
    return session


async def _bring_up(run: _Run, session: NetworkSession, stopper: asyncio.Task[Any]) -> None:
    """Wait for every station to reach its phase (or the bring-up timeout), or for a signal (*stopper*)."""
    bring = run.loop.create_task(session.bring_up(run.opts.bringup_timeout_s))
    done, _ = await asyncio.wait({bring, stopper}, return_when=asyncio.FIRST_COMPLETED)
    if bring not in done:
        bring.cancel()
        await asyncio.gather(bring, return_exceptions=True)


async def _timeline(run: _Run, session: NetworkSession, runner: TimelineRunner, stopper: asyncio.Task[Any],
                    length: int | None) -> None:
    """Run the timeline with the live status from the end of bring-up until its end (*length*), --duration or a
    signal (*stopper*)."""
    config, opts, loop, status = run.config, run.opts, run.loop, run.status
    session.not_up()
    log.info("network_up", stations=len(config.station))
    if not opts.include_bringup:
        session.reset_metrics()  # the report is about the running network, not five processes starting
    t0 = loop.time()
    if run.sampler is not None:
        run.sampler.start(t0)
        runner.on_action, runner.on_check = run.sampler.on_step, run.sampler.on_check
    if run.ops is not None:
        run.ops.log.start()
    tasks = [loop.create_task(runner.run(t0))]
    frame = _framer(config, session, runner.timeline, runner.ops.scales, t0, length)
    if status is not None:
        status.start()
        tasks.append(loop.create_task(_status_loop(status, frame, session.slack)))
    end = loop.create_task(sleep_until(t0 + length / 1e9)) if length is not None else None
    waiters = {stopper} | ({end} if end else set())
    if end is None and not config.timeline:
        _notice(opts, "no_end", "running until Ctrl-C (no timeline, no --duration)")
    await asyncio.wait(waiters, return_when=asyncio.FIRST_COMPLETED)
    for task in [*tasks, *waiters]:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    session.problems.extend(runner.timeline.action_errors)
    if status is not None:
        status.stop(frame(status.width))


async def _report(run: _Run, session: NetworkSession, timeline: Timeline) -> dict[str, Any]:
    """The trace's last rows, the slaves' last figures, DISCONNECT (while the slaves still run), the timeline's
    checks, the report."""
    if run.sampler is not None:
        await run.sampler.close()
    await session.refresh_slave_stats()
    await session.close_masters()
    timeline.results[:] = timeline.results_naming_stalls(session.metrics.stalls)
    for c in timeline.results:
        session.metrics.record_check(c.at_s, c.what, c.ok, c.detail, c.cause, station=c.station)
    interrupted = run.caught[0].name if run.caught else None
    trace = {} if run.opts.trace_path is None else {"trace": str(run.opts.trace_path),
                                                     "trace_interval_ns": run.opts.trace_interval_ns}
    return await session.report(assertions=run.opts.assertions, slave_stats=False, extra_meta={
        "interrupted": interrupted, "not_run": [s.describe for s in timeline.not_run()], **trace})


async def _close(run: _Run) -> None:
    """Release what the run holds, whatever happened before: the control endpoint, the live status, the session
    (its workers), the capture, the signal handlers."""
    if run.web is not None:
        await run.web.stop()
    if run.control is not None:
        run.control.close()
    if run.sampler is not None:
        await run.sampler.close()
    if run.status is not None:
        run.status.stop()
    if run.session is not None:
        await run.session.close()
    capture = run.opts.capture
    if capture is not None:  # in a thread on the wall clock; in place on the virtual clock, whose loop would
        # busy-poll (and fight the closing thread for the GIL) while it waits for a thread
        closed = capture.close() if run.opts.clock == "virtual" else await run.loop.run_in_executor(None, capture.close)
        print(closed.summary(), file=sys.stderr)
    for sig in SIGNAL_EXIT:
        run.loop.remove_signal_handler(sig)


def _verdict(run: _Run, report: dict[str, Any], timeline: Timeline, session: NetworkSession) -> RunOutcome:
    """Write the report, judge the run (:class:`~.verdict.Verdict`), print the summary."""
    opts = run.opts
    if opts.report_path is not None:
        write_report(opts.report_path, report)
    html_failed = _write_html(run, report)
    verdict = Verdict.of(timeline, report, len(session.unreached), run.caught[0] if run.caught else None)
    files = [f"{what}: {path}" for what, path in (("report", opts.report_path), ("trace", opts.trace_path),
                                                  ("HTML report", opts.report_html)) if path is not None]
    print_summary(run.config, report, timeline, verdict, session.problems, opts.duration_ns, files)
    return RunOutcome(verdict.exit_code or int(html_failed), report, timeline.results, session.problems)


def _open_trace(run: _Run, session: NetworkSession) -> TraceSampler | None:
    """The trace's sampler, writing to ``--trace``'s file or, for ``--report-html`` alone, a temporary one (removed
    once the page is written); None, with a notice, when the file cannot be opened."""
    from ...metrics.trace import TraceWriter

    opts = run.opts
    path = opts.trace_path
    if path is None:
        fd, name = tempfile.mkstemp(prefix="mlink-sim-trace-", suffix=".csv")
        os.close(fd)
        path = Path(name)
    run.trace_file = path
    try:
        writer = TraceWriter(path)
    except OSError as exc:
        _notice(opts, "trace_failed", f"mlink-sim: trace {path}: {exc.strerror or exc}; the run goes on without it")
        session.problems.append(f"trace {path}: {exc.strerror or exc}")
        return None
    return TraceSampler(session, writer, opts.trace_interval_ns)


def _write_html(run: _Run, report: dict[str, Any]) -> bool:
    """``--report-html``: the page, with the run's trace read back (a temporary trace is removed after); True when
    it could not be written (said on stderr; the run then fails)."""
    from ...metrics.html import check_moments, write_html
    from ...metrics.trace import TraceError, read_trace

    opts, path = run.opts, run.opts.report_html
    if path is None:
        return False
    trace = None
    try:
        if run.trace_file is not None and run.sampler is not None:
            try:
                trace = read_trace(run.trace_file, moments=check_moments(report))
            except TraceError as exc:
                _notice(opts, "trace_unreadable", f"mlink-sim: {exc}; the HTML report has no traces")
        write_html(path, report, trace)
    except OSError as exc:
        _notice(opts, "report_html_failed", f"mlink-sim: --report-html {path}: {exc.strerror or exc}")
        return True
    finally:
        _drop_temporary_trace(run)
    return False


def _drop_temporary_trace(run: _Run) -> None:
    """Remove the temporary trace of ``--report-html`` without ``--trace``."""
    if run.opts.trace_path is None and run.trace_file is not None:
        run.trace_file.unlink(missing_ok=True)


def _notice(opts: RunOptions, event: str, text: str) -> None:
    """A message for the user on stderr: plain text, or a JSON log line with ``--log-json`` (stderr then carries
    JSON lines only)."""
    if opts.log_json:
        log.warning(event, message=text)
    else:
        print(text, file=sys.stderr, flush=True)


def cut_by_duration(config: Config, duration_ns: int | None) -> list[TimelineStep]:
    """The timeline steps a ``--duration`` of *duration_ns* ends the run before (in order of time)."""
    if duration_ns is None:
        return []
    return [s for s in sorted(config.timeline, key=lambda s: s.at) if s.at >= duration_ns]


def _framer(config: Config, session: NetworkSession, timeline: Timeline, scales: dict[int, Any], t0: float,
            length: int | None) -> Callable[[int | None], list[str]]:
    """A function drawing the current status frame for a terminal of a given width (None: not a terminal;
    docs/timing.md: bounded work per call)."""
    loop = asyncio.get_running_loop()
    p99 = WorstP99()
    assert session.net is not None

    def frame(width: int | None) -> list[str]:
        step = timeline.current
        return render_lines(StatusInfo(
            config=config, net=session.net, metrics=session.metrics, scales=scales,
            elapsed_s=loop.time() - t0, total_s=None if length is None else length / 1e9,
            step=step.describe if step else None, p99_ns=p99.step(session.metrics)), width)

    return frame


async def _status_loop(status: LiveStatus, frame: Callable[[int | None], list[str]], slack: Slack) -> None:
    """A frame every ``status.interval``, drawn in a cycle's slack (it starts when the cycle's answers are in)."""
    while True:
        await asyncio.sleep(status.interval)
        await slack.wait()
        status.show(frame(status.width))
