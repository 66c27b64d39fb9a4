"""Multi-host testbed without Docker: every station and the master in its own Linux network namespace.

``scripts/netns-testbed CONFIG`` (a wrapper around ``python -m mlink_sim.testbed.netns``) builds::

      ┌ <prefix>-m ─────┐   ┌ <prefix>-s21 ───┐   ┌ <prefix>-s22 ───┐
      │ master          │   │ slave 0x21      │   │ slave 0x22      │
      │ eth0 198.18.0.1 │   │ eth0 198.18.0.2 │   │ eth0 198.18.0.3 │
      └──────┬──────────┘   └──────┬──────────┘   └──────┬──────────┘
        <prefix>h0            <prefix>h1             <prefix>h2        veth pairs, host ends on
      ───────┴──────────── <prefix>br (bridge) ──────────┴──────────   the bridge; no host address

Addresses come from 198.18.0.0/15 (RFC 2544 benchmarking, never routed): the master .1, stations .2 on in
config order. Then: every slave started with ``ip netns exec`` (``--allow-master`` the master's address: no other
namespace changes a station) and waited for (its ready line), a NOP from the
master's namespace to every station, the master with the config's timeline and a report; its exit code is the
testbed's. Everything with the prefix is removed afterwards – on success, failure, Ctrl-C or SIGTERM – and before
starting (leftovers of the same prefix, and of ``mls-<pid>`` runs whose process is gone).

:func:`make_plan` is pure (names, addresses, commands) and tested without privileges; :class:`Testbed` runs it.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from ..config import Config, ConfigError, load_config, parse_duration_ns
from ..aio.run.supervisor import die_with_parent
from . import firewall

__all__ = ["Node", "Plan", "make_plan", "check_prefix", "cleanup", "stale_prefixes", "Testbed", "TestbedError",
           "main", "DEFAULT_PORT", "SUBNET", "list_netns", "list_links", "pid_alive", "stop_pids"]

SUBNET = "198.18.0"  #: a /24 inside 198.18.0.0/15 (RFC 2544); every testbed has its own bridge, so runs may overlap
PREFIX_LEN = 24
DEFAULT_PORT = 47001
MAX_PREFIX = 11  #: "<prefix>h237" must fit IFNAMSIZ (15 characters)
_PREFIX_RE = re.compile(r"^[a-z][a-z0-9-]*$")
_DEFAULT_FAMILY = re.compile(r"^(mls-(\d+))(?:-|br$|h\d+$)")  #: names of default-prefix (mls-<pid>) testbeds


class TestbedError(RuntimeError):
    """Setting the testbed up or starting a process in it failed; the message says what and where the log is."""


# -- the plan (pure) ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Node:
    """The master or one station: its namespace, the host end of its veth pair and its address."""

    role: str  #: "master" or "station"
    index: int  #: 0 for the master, 1… for the stations in config order
    netns: str
    veth: str  #: host end, on the bridge; the namespace end is called eth0
    ip: str
    address: int | None = None  #: station address
    link_name: str | None = None  #: "ml1"/"ml2"/"ml3"
    frame_size: int | None = None

    @property
    def name(self) -> str:
        return "master" if self.address is None else f"station-{self.address:02x}"


@dataclass(frozen=True)
class Plan:
    """Every name, address and command of one testbed."""

    prefix: str
    bridge: str
    port: int
    master: Node
    stations: tuple[Node, ...]
    slave_flags: tuple[str, ...] = ()  #: the network's host-stall policy for the slaves (docs/timing.md)

    @property
    def nodes(self) -> tuple[Node, ...]:
        return (self.master, *self.stations)

    def setup_commands(self, ip: str = "ip") -> list[list[str]]:
        """``ip`` invocations that build the testbed, in order."""
        cmds = [[ip, "link", "add", self.bridge, "type", "bridge"], [ip, "link", "set", self.bridge, "up"]]
        for n in self.nodes:
            cmds += [
                [ip, "netns", "add", n.netns],
                [ip, "-n", n.netns, "link", "set", "lo", "up"],
                [ip, "link", "add", n.veth, "type", "veth", "peer", "name", "eth0", "netns", n.netns],
                [ip, "link", "set", n.veth, "master", self.bridge],
                [ip, "link", "set", n.veth, "up"],
                [ip, "-n", n.netns, "addr", "add", f"{n.ip}/{PREFIX_LEN}", "dev", "eth0"],
                [ip, "-n", n.netns, "link", "set", "eth0", "up"],
            ]
        return cmds

    def endpoint(self, node: Node) -> str:
        assert node.address is not None
        return f"0x{node.address:02X}={node.ip}:{self.port}"

    def slave_argv(self, node: Node, config_path: str, python: str = sys.executable, ip: str = "ip") -> list[str]:
        assert node.address is not None
        return [ip, "netns", "exec", node.netns, python, "-m", "mlink_sim", "slave", "--config", config_path,
                "--only", f"0x{node.address:02X}", "--endpoint", self.endpoint(node), "--ready-json",
                "--allow-master", self.master.ip, *self.slave_flags]  # fmt: skip

    def reach_argv(self, python: str = sys.executable, ip: str = "ip") -> list[str]:
        targets = [f"{self.endpoint(n)}/{n.link_name}/{n.frame_size}" for n in self.stations]
        return [ip, "netns", "exec", self.master.netns, python, "-m", "mlink_sim.testbed.reach", *targets]

    def master_argv(
        self,
        config_path: str,
        *,
        report: str | None,
        duration: str | None = None,
        asserts: tuple[str, ...] = (),
        bringup_timeout: str | None = None,
        python: str = sys.executable,
        ip: str = "ip",
    ) -> list[str]:
        argv = [ip, "netns", "exec", self.master.netns, python, "-m", "mlink_sim", "master", config_path]
        for n in self.stations:
            argv += ["--endpoint", self.endpoint(n)]
        if report is not None:
            argv += ["--report", report]
        argv.append("--no-status")
        if duration is not None:
            argv += ["--duration", duration]
        if bringup_timeout is not None:
            argv += ["--bringup-timeout", bringup_timeout]
        for expr in asserts:
            argv += ["--assert", expr]
        return argv


def check_prefix(prefix: str) -> str:
    """The prefix if it makes valid interface names (≤ 11 characters, ``[a-z][a-z0-9-]*``), else ValueError."""
    if not _PREFIX_RE.match(prefix) or len(prefix) > MAX_PREFIX or prefix.endswith("-"):
        raise ValueError(f"prefix must be 1–{MAX_PREFIX} characters [a-z0-9-], starting with a letter, "
                         f"not ending in '-', got {prefix!r}")
    return prefix


def make_plan(config: Config, prefix: str, port: int = DEFAULT_PORT) -> Plan:
    """Names and addresses for *config*: master 198.18.0.1, stations 198.18.0.2… in config order."""
    check_prefix(prefix)
    if len(config.station) > 253:  # pragma: no cover - addresses end at EFH
        raise ValueError("a /24 testbed holds at most 253 stations")
    master = Node("master", 0, f"{prefix}-m", f"{prefix}h0", f"{SUBNET}.1")
    stations = tuple(
        Node("station", i, f"{prefix}-s{st.address:02x}", f"{prefix}h{i}", f"{SUBNET}.{i + 1}", st.address,
             st.link.name.lower() if st.link else None, st.frame_size)
        for i, st in enumerate(config.station, start=1)
    )  # fmt: skip
    return Plan(prefix, f"{prefix}br", port, master, stations, tuple(config.network.slave_flags()))


# -- cleanup (idempotent) -------------------------------------------------------------------------------------


def _ip(ip: str, *args: str, check: bool = False) -> subprocess.CompletedProcess[str]:
    result = subprocess.run([ip, *args], capture_output=True, text=True, timeout=30)
    if check and result.returncode != 0:
        raise TestbedError(f"`{ip} {' '.join(args)}` failed: {result.stderr.strip() or result.returncode}")
    return result


def list_netns(ip: str = "ip") -> list[str]:
    return [line.split()[0] for line in _ip(ip, "netns", "list").stdout.splitlines() if line.strip()]


def list_links(ip: str = "ip") -> list[str]:
    names = []
    for line in _ip(ip, "-o", "link", "show").stdout.splitlines():
        parts = line.split(":", 2)
        if len(parts) >= 2:
            names.append(parts[1].strip().split("@")[0])
    return names


def _ours(prefix: str) -> tuple[re.Pattern[str], re.Pattern[str]]:
    p = re.escape(prefix)
    return re.compile(rf"^{p}-(m|s[0-9a-f]+)$"), re.compile(rf"^{p}(br|h\d+)$")


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stale_prefixes(ip: str = "ip") -> list[str]:
    """Default prefixes (``mls-<pid>``) with namespaces or links left behind by a process that is gone."""
    found = set()
    for name in [*list_netns(ip), *list_links(ip)]:
        m = _DEFAULT_FAMILY.match(name)
        if m and not pid_alive(int(m.group(2))):
            found.add(m.group(1))
    return sorted(found)


def stop_pids(pids: list[int], grace: float = 2.0) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    end = time.monotonic() + grace
    while time.monotonic() < end and any(pid_alive(p) for p in pids):
        time.sleep(0.05)
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


def cleanup(prefix: str, ip: str = "ip") -> list[str]:
    """Remove every namespace (stopping what runs in it), bridge, veth and FORWARD rule of *prefix*; what was
    removed.

    Idempotent: a second call finds nothing and removes nothing.
    """
    ns_re, link_re = _ours(prefix)
    removed = []
    for ns in list_netns(ip):
        if not ns_re.match(ns):
            continue
        pids = [int(p) for p in _ip(ip, "netns", "pids", ns).stdout.split() if p.isdigit()]
        if pids:
            stop_pids(pids)
        if _ip(ip, "netns", "del", ns).returncode == 0:
            removed.append(ns)
    for name in list_links(ip):  # veths whose namespace end is gone are gone too; the bridge remains
        if link_re.match(name) and _ip(ip, "link", "del", name).returncode == 0:
            removed.append(name)
    return removed + firewall.remove_rules(prefix)


def leftovers(prefix: str, ip: str = "ip") -> list[str]:
    ns_re, link_re = _ours(prefix)
    return ([n for n in list_netns(ip) if ns_re.match(n)] + [n for n in list_links(ip) if link_re.match(n)]
            + [" ".join(rule) for rule in firewall.rules_of(prefix)])


# -- running it -----------------------------------------------------------------------------------------------



class Interrupted(Exception):
    """SIGINT/SIGTERM/SIGHUP arrived; the testbed is torn down and the exit code is 128 + signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _say(text: str) -> None:
    print(f"netns-testbed: {text}", file=sys.stderr, flush=True)


class Testbed:
    """Builds a :class:`Plan`, runs its processes, tears it down."""

    def __init__(self, plan: Plan, config_path: str, log_dir: Path, *, ip: str = "ip",
                 python: str = sys.executable) -> None:  # fmt: skip
        self.plan = plan
        self.config_path = config_path
        self.log_dir = log_dir
        self.ip = ip
        self.python = python
        self.procs: dict[str, subprocess.Popen[bytes]] = {}

    def _spawn(self, name: str, argv: list[str], *, to_files: bool = True) -> subprocess.Popen[bytes]:
        out: Any = None
        err: Any = None
        if to_files:
            out = open(self.log_dir / f"{name}.out", "wb")  # noqa: SIM115 - handed to the child
            err = open(self.log_dir / f"{name}.log", "wb")  # noqa: SIM115
        try:
            proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=out, stderr=err, process_group=0,
                                    preexec_fn=die_with_parent, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        finally:
            for fh in (out, err):
                if fh is not None:
                    fh.close()
        self.procs[name] = proc
        return proc

    def _tail(self, name: str, lines: int = 12) -> str:
        try:
            text = (self.log_dir / f"{name}.log").read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join("    " + line for line in text[-lines:])

    def up(self) -> None:
        """The bridge, the namespaces and their veths; a FORWARD rule for the bridge (a Docker engine sets the
        chain's policy to DROP: :mod:`~mlink_sim.testbed.firewall`)."""
        for argv in self.plan.setup_commands(self.ip):
            _ip(argv[0], *argv[1:], check=True)
        if error := firewall.allow_bridge(self.plan.bridge, self.plan.prefix):  # an ACCEPT policy needs none
            _say(f"{error}; if the FORWARD chain drops bridged frames, the stations cannot be reached")

    def start_slaves(self, timeout: float = 15.0) -> None:
        """Start every slave in its namespace and wait until each has printed its ready line."""
        waiting = {}
        for n in self.plan.stations:
            self._spawn(n.name, self.plan.slave_argv(n, self.config_path, self.python, self.ip))
            waiting[n.name] = n
        end = time.monotonic() + timeout
        while waiting:
            for name in list(waiting):
                if self._ready(name):
                    del waiting[name]
                elif self.procs[name].poll() is not None:
                    raise TestbedError(f"{name} exited with {self.procs[name].returncode} before it was ready "
                                       f"(log: {self.log_dir / (name + '.log')}):\n{self._tail(name)}")
            if waiting and time.monotonic() > end:
                names = ", ".join(sorted(waiting))
                raise TestbedError(f"not ready after {timeout:g}s: {names} (logs in {self.log_dir})")
            if waiting:
                time.sleep(0.02)

    def _ready(self, name: str) -> bool:
        try:
            text = (self.log_dir / f"{name}.out").read_text(errors="replace")
        except OSError:
            return False
        for line in text.splitlines():
            with contextlib.suppress(ValueError):
                info = json.loads(line)
                if isinstance(info, dict) and info.get("event") == "ready":
                    return True
        return False

    def check_reach(self) -> None:
        """A NOP from the master's namespace to every station; names the ones that do not answer."""
        result = subprocess.run(self.plan.reach_argv(self.python, self.ip), capture_output=True, text=True,
                                timeout=30, env={**os.environ, "PYTHONUNBUFFERED": "1"})  # fmt: skip
        if result.returncode != 0:
            detail = (result.stdout + result.stderr).strip()
            raise TestbedError(
                "from the master's namespace:\n    " + detail.replace("\n", "\n    ")
                + "\n  (over the bridge: the testbed accepts its bridge's frames in iptables' FORWARD chain, but a "
                "firewall of another kind – nftables tables of its own, ebtables – may drop them; see docs/testbeds.md)"
            )

    def run_master(self, *, report: str | None, duration: str | None, asserts: tuple[str, ...],
                   bringup_timeout: str | None, limit_s: float) -> int:  # fmt: skip
        argv = self.plan.master_argv(self.config_path, report=report, duration=duration, asserts=asserts,
                                     bringup_timeout=bringup_timeout, python=self.python, ip=self.ip)
        proc = self._spawn("master", argv, to_files=False)  # its summary goes to our stdout/stderr
        try:
            return proc.wait(timeout=limit_s)
        except subprocess.TimeoutExpired:
            _say(f"the master was still running after {limit_s:g}s; stopping it")
            self._stop(proc, signal.SIGTERM, 5.0)
            return 1

    @staticmethod
    def _stop(proc: subprocess.Popen[bytes], sig: int, grace: float) -> None:
        if proc.poll() is not None:
            return
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(sig)
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            proc.wait()

    def stop_processes(self) -> None:
        """The master first (SIGINT, as from a terminal), then every slave (SIGTERM); SIGKILL after a grace."""
        master = self.procs.get("master")
        if master is not None:
            self._stop(master, signal.SIGINT, 10.0)
        slaves = [p for name, p in self.procs.items() if name != "master"]
        for p in slaves:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    p.send_signal(signal.SIGTERM)
        for p in slaves:
            self._stop(p, signal.SIGTERM, 3.0)


class _Signals:
    """While armed, SIGINT/SIGTERM/SIGHUP raise :class:`Interrupted` (once); disarmed, they are only recorded, so
    that a second Ctrl-C cannot cut the teardown short."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self) -> None:
        self.armed = False
        self.received: list[int] = []
        self._old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        self.received.append(signum)
        if self.armed:
            self.armed = False
            raise Interrupted(signum)

    def __enter__(self) -> _Signals:
        self._old = {s: signal.signal(s, self._handler) for s in self.SIGNALS}
        self.armed = True
        return self

    def __exit__(self, *exc: object) -> None:
        self.armed = False
        for s, h in self._old.items():
            signal.signal(s, h)


def _find_ip() -> str | None:
    return shutil.which("ip") or next((p for p in ("/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip") if os.access(p, os.X_OK)),
                                      None)


def preflight() -> str:
    """The ``ip`` binary if this process may build network namespaces; else a :class:`click.UsageError`."""
    if not sys.platform.startswith("linux"):
        raise click.UsageError("network namespaces need Linux")
    if os.geteuid() != 0:
        raise click.UsageError("needs root to create network namespaces, veth pairs and a bridge; run it with sudo "
                               "(e.g. sudo scripts/netns-testbed CONFIG)")
    ip = _find_ip()
    if ip is None:
        raise click.UsageError("needs the `ip` command of iproute2 (apt-get install -y iproute2)")
    result = _ip(ip, "netns", "list")
    if result.returncode != 0:
        raise click.UsageError(f"`ip netns` is not usable here: {result.stderr.strip()}")
    return ip


def _limit_s(config: Config, duration: str | None, bringup_timeout: str | None) -> float:
    run_ns = parse_duration_ns(duration, default_unit="s") if duration else (config.run_length_ns or 30_000_000_000)
    bring_ns = parse_duration_ns(bringup_timeout, default_unit="s") if bringup_timeout else 10_000_000_000
    return (run_ns + bring_ns) / 1e9 + 30.0


def _give_to_sudo_user(path: Path) -> None:
    uid, gid = os.environ.get("SUDO_UID"), os.environ.get("SUDO_GID")
    if uid and gid and path.exists():
        with contextlib.suppress(OSError, ValueError):
            os.chown(path, int(uid), int(gid))


def _sweep(ip: str, prefix: str) -> None:
    for stale in stale_prefixes(ip):
        if stale != prefix and (removed := cleanup(stale, ip)):
            _say(f"removed leftovers of an earlier run: {' '.join(removed)}")
    if removed := cleanup(prefix, ip):
        _say(f"removed leftovers with prefix {prefix}: {' '.join(removed)}")


@click.command("netns-testbed", context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110})
@click.argument("config_path", metavar="CONFIG", required=False)
@click.option("--duration", help="Passed to `mlink-sim master` (default: the config's timeline).")
@click.option("--report", default="report.json", show_default=True, help="Where the master writes its report.")
@click.option("--assert", "asserts", multiple=True, metavar="EXPR", help="Passed to `mlink-sim master`; repeatable.")
@click.option("--bringup-timeout", help="Passed to `mlink-sim master`.")
@click.option("--port", default=DEFAULT_PORT, show_default=True, type=click.IntRange(1, 65535),
              help="UDP port of every station (each has its own address).")
@click.option("--prefix", help="Name prefix of namespaces and links (default: mls-<pid>, ≤ 11 characters).")
@click.option("--log-dir", type=click.Path(file_okay=False), help="Slave logs (default: a temp dir, kept on failure).")
@click.option("--python", "python", default=sys.executable, show_default=False, type=click.Path(dir_okay=False),
              help="Interpreter that runs mlink-sim in the namespaces (default: the one running this).")
@click.option("--keep", is_flag=True, help="Leave the namespaces in place afterwards (remove with --cleanup).")
@click.option("--cleanup", "cleanup_only", is_flag=True,
              help="Only remove leftovers: of --prefix, or of every mls-<pid> run whose process is gone.")
def main(config_path: str | None, duration: str | None, report: str, asserts: tuple[str, ...],
         bringup_timeout: str | None, port: int, prefix: str | None, log_dir: str | None, python: str, keep: bool,
         cleanup_only: bool) -> None:  # fmt: skip
    """Run the network in CONFIG with every station and the master in its own network namespace, joined by a
    bridge; exit with the master's code (0: every check held). Needs root and iproute2."""
    given_prefix = prefix is not None
    try:
        prefix = check_prefix(prefix or f"mls-{os.getpid()}")
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--prefix") from None
    ip = preflight()
    if cleanup_only:
        targets = [prefix] if given_prefix else stale_prefixes(ip)
        removed = [name for p in targets for name in cleanup(p, ip)]
        _say(f"removed {' '.join(removed)}" if removed else "nothing to remove")
        sys.exit(0)
    if config_path is None:
        raise click.UsageError("missing CONFIG")
    for text, flag in ((duration, "--duration"), (bringup_timeout, "--bringup-timeout")):
        try:
            if text is not None:
                parse_duration_ns(text, default_unit="s")
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint=flag) from None
    try:
        config = load_config(config_path)
    except ConfigError as exc:
        click.echo(f"netns-testbed: {exc}", err=True)
        sys.exit(2)
    plan = make_plan(config, prefix, port)
    sys.exit(run_testbed(plan, config, config_path, ip=ip, report=report, duration=duration, asserts=asserts,
                         bringup_timeout=bringup_timeout, log_dir=log_dir, keep=keep, python=python))


def run_testbed(plan: Plan, config: Config, config_path: str, *, ip: str, report: str | None,
                duration: str | None = None, asserts: tuple[str, ...] = (), bringup_timeout: str | None = None,
                log_dir: str | None = None, keep: bool = False, python: str = sys.executable) -> int:  # fmt: skip
    """Build, run, tear down; the exit code (the master's, 1 on a testbed failure, 128+N on signal N)."""
    logs = Path(log_dir) if log_dir else Path(tempfile.mkdtemp(prefix=f"{plan.prefix}-logs-"))
    logs.mkdir(parents=True, exist_ok=True)
    report_path = Path(report).resolve() if report else None
    if report_path is not None:
        report_path.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(FileNotFoundError):
            report_path.unlink()  # a stale report must not pass for this run's
    bed = Testbed(plan, str(Path(config_path).resolve()), logs, ip=ip, python=python)
    code = 1
    with _Signals() as signals:
        try:
            _sweep(ip, plan.prefix)
            bed.up()
            _say(f"{len(plan.stations)} station namespace(s) + master on bridge {plan.bridge}: "
                 + ", ".join(f"{n.name}={n.ip}" for n in plan.nodes))
            bed.start_slaves()
            bed.check_reach()
            _say("every station answers; starting the master")
            code = bed.run_master(report=str(report_path) if report_path else None, duration=duration,
                                  asserts=asserts, bringup_timeout=bringup_timeout,
                                  limit_s=_limit_s(config, duration, bringup_timeout))
        except Interrupted as exc:
            _say(f"{exc} – tearing the testbed down")
            code = 128 + exc.signum
        except (TestbedError, subprocess.SubprocessError, OSError) as exc:
            _say(str(exc))
            code = 1
        finally:
            signals.armed = False
            if signals.received and code < 128:
                code = 128 + signals.received[0]
            bed.stop_processes()
            if keep:
                _say(f"kept: {' '.join(leftovers(plan.prefix, ip))} (remove with: scripts/netns-testbed --cleanup "
                     f"--prefix {plan.prefix})")
            else:
                cleanup(plan.prefix, ip)
                if left := leftovers(plan.prefix, ip):
                    _say(f"could not remove: {' '.join(left)}")
                    code = code or 1
            if report_path is not None:
                _give_to_sudo_user(report_path)
            if code == 0 and log_dir is None:
                shutil.rmtree(logs, ignore_errors=True)
            else:
                _say(f"logs: {logs}")
    if report_path is not None and code == 0:
        _say(f"report: {report_path}")
    return code


if __name__ == "__main__":
    main(prog_name="netns-testbed")
