"""Launch the planning service (ROS launch is not needed): recorder, planner node, radar replay or simulator.

    mal-launch --replay data/thesis_radar.mcap --out out/main     # main job: replay, plan, record, stop
    mal-launch --simulate --duration 60 --out out/sim             # radar simulator instead of a bag
    mal-launch --closed-loop --scenario scenarios/thesis_wind.yaml --out out/cl   # aircraft fly the plans

``--closed-loop`` runs the flight simulator (:mod:`mal_planner.ros.radar_sim`) as the radar source: its aircraft
fly the published plans under guidance, in the scenario's wind plus gusts, and it publishes ``/clock``; the
planner runs with ``use_sim_time`` (so the simulation may run faster than real time, ``--sim-speed``, while
planning time counts in full), replans when a track strays ten path accuracies from its plan, and the run
ends when every aircraft has landed, with the simulator's summary of what was flown.

Each part runs as its own process (``python -m mal_planner.ros.<part>``); their output is prefixed with
the part's name and also written to ``<out>/logs/<part>.log``. SIGINT/SIGTERM are forwarded to the
children; the recorder is stopped last so that the bag is complete. The children die with the launcher even
when it is killed (SIGKILL): on Linux each gets SIGTERM when its parent dies (PR_SET_PDEATHSIG). A child that
ends unasked is reported with its exit code, a signal by name (``planner killed by SIGTERM (exit -15)``).
With ``--respawn`` (ROS 2 launch's ``respawn=True``, ``respawn_delay``) a planner that ends unasked while the
radar source runs is started again with the same arguments after ``--respawn-delay`` seconds, at most
``--respawn-max`` times; the recorder goes on recording into the same bag. A planner stopped by the launcher
is not respawned, nor one that ends after a finite source has ended (no radar would come for a new one).
The inputs (bag, scenario, params file) are checked before any child starts or any folder is made: a bad
one ends the launcher with exit code 2 and one line on stderr.

With a finite radar source (a bag, or ``--simulate --duration S``) the launcher stops everything once
the source has ended and the planner has published its plan (it watches ``<out>/planner_status.json``),
then prints a summary table. ``--keep-running`` keeps the planner up until Ctrl-C instead.

Network: when ``CYCLONEDDS_URI`` is not set, a loopback-only Cyclone DDS configuration (127.0.0.1, no
multicast) is written to ``<out>/cyclonedds.xml`` and used, so a run never touches the network. Set
``CYCLONEDDS_URI`` (and ``ROS_DOMAIN_ID``) yourself to talk to other machines or to ROS 2 tools.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from mal_planner.ros.node_outputs import STATUS_FILE, read_status, summary_table, write_closed_loop_params
from mal_planner.ros.transport.loopback import write_loopback_config

REPO = Path(__file__).resolve().parents[3]
READY = {"recorder": "record: recording", "planner": "planner ready"}
STOP_TIMEOUT_S = 15.0
RESPAWNABLE = ("planner",)
# Not ROS 2 launch's 0: a planner that fails at start-up would burn its attempts in a busy loop; 1 s is small next to
# what a restart costs anyway (interpreter and CasADi import, the duplicate probe, settle_time_s).
RESPAWN_DELAY_S = 1.0
RESPAWN_MAX = 3


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _die_with_parent(parent: int) -> Any:
    """A ``preexec_fn``: the child gets SIGTERM when the launcher dies, even by SIGKILL (Linux only)."""
    if not sys.platform.startswith("linux"):
        return None
    libc = ctypes.CDLL(None, use_errno=True)

    def preexec() -> None:
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != parent:  # the launcher died before prctl: no signal would come
            os.kill(os.getpid(), signal.SIGTERM)

    return preexec


def exit_text(code: int | None) -> str:
    """``exited with code 1``, ``killed by SIGTERM (exit -15)``: how a child ended, as launch reports it."""
    if code is None:
        return "is still running"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"killed by {name} (exit {code})"
    return f"exited with code {code}"


class Child:
    """One child process; its merged output is echoed with a prefix and saved to a log file."""

    def __init__(self, name: str, args: Sequence[str], env: dict[str, str], log_dir: Path,
                 append: bool = False) -> None:
        self.name, self.args, self.env, self.log_dir = name, list(args), env, log_dir
        self.ready = threading.Event()
        self._ready_text = READY.get(name)
        self._log: TextIO = (log_dir / f"{name}.log").open("a" if append else "w", encoding="utf-8")
        self.proc = subprocess.Popen([sys.executable, "-u", "-m", *args], env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, start_new_session=True,
                                     preexec_fn=_die_with_parent(os.getpid()))
        self._pump = threading.Thread(target=self._read, daemon=True)
        self._pump.start()
        if self._ready_text is None:
            self.ready.set()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._log.write(line)
            self._log.flush()
            sys.stdout.write(f"[{self.name}] {line}")
            sys.stdout.flush()
            if self._ready_text and self._ready_text in line:
                self.ready.set()
        self.ready.set()

    def running(self) -> bool:
        return self.proc.poll() is None

    def stop(self, sig: int = signal.SIGTERM, timeout: float = STOP_TIMEOUT_S) -> int:
        """Send ``sig``, wait, kill if needed; the exit code."""
        if self.running():
            try:
                self.proc.send_signal(sig)
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                print(f"launch: {self.name} did not stop within {timeout:.0f} s: killed", flush=True)
                self.proc.kill()
                self.proc.wait()
        self._pump.join(timeout=2.0)
        self._log.close()
        return self.proc.returncode


def _default(name: str) -> str:
    return name if Path(name).exists() else str(REPO / name)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-launch", description=__doc__.split("\n")[0],
                                epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--replay", metavar="BAG", help="replay recorded radar tracks from this bag")
    src.add_argument("--simulate", action="store_true", help="run the radar simulator on the scenario")
    src.add_argument("--closed-loop", action="store_true",
                     help="the simulated aircraft fly the plans until everyone has landed (simulated time)")
    p.add_argument("--scenario", default=None, help="scenario YAML (default scenarios/thesis.yaml)")
    p.add_argument("--params", default=None, help="planner params YAML (default config/planner.params.yaml)")
    p.add_argument("--out", default="out/main", help="output folder (default out/main)")
    rec = p.add_mutually_exclusive_group()
    rec.add_argument("--record", metavar="BAG", default=None, help="record to this bag (default <out>/bag)")
    rec.add_argument("--no-record", action="store_true", help="do not record")
    p.add_argument("--rate", type=float, default=1.0, help="replay speed factor (default 1)")
    p.add_argument("--restamp", action="store_true", help="replay: shift stamps to the publish time")
    p.add_argument("--sim-rate", type=float, default=2.0, help="simulator rate [Hz] (default 2)")
    p.add_argument("--duration", type=float, default=0.0, help="simulator duration [s], 0 = until Ctrl-C")
    p.add_argument("--sim-speed", type=float, default=4.0,
                   help="closed loop: simulated seconds per wall-clock second (default 4; 1 = real time)")
    p.add_argument("--gust-kt", type=float, default=1.0, help="closed loop: gusts, rms per axis [kt] (default 1)")
    p.add_argument("--noise-m", type=float, default=10.0, help="closed loop: radar noise sigma [m] (default 10)")
    p.add_argument("--timeout", type=float, default=300.0,
                   help="after the radar source ended, wait this long for the plan (default 300 s)")
    p.add_argument("--keep-running", action="store_true", help="do not stop when the radar source ends")
    p.add_argument("--respawn", action="store_true",
                   help="restart the planner when it ends unasked (crash, SIGKILL), as ROS 2 launch's respawn=True")
    p.add_argument("--respawn-delay", type=float, default=RESPAWN_DELAY_S, metavar="S",
                   help=f"wait this long before a respawn (default {RESPAWN_DELAY_S:g} s)")
    p.add_argument("--respawn-max", type=int, default=RESPAWN_MAX, metavar="N",
                   help=f"respawn at most N times, then end as without --respawn (default {RESPAWN_MAX})")
    args = p.parse_args(argv)
    if args.rate < 0 or args.sim_rate <= 0 or args.duration < 0 or args.timeout <= 0 or args.sim_speed <= 0 \
            or args.gust_kt < 0 or args.noise_m < 0:
        p.error("--rate, --duration, --gust-kt, --noise-m must be >= 0; --sim-rate, --sim-speed, --timeout > 0")
    return args


def child_env(out: Path) -> dict[str, str]:
    """Environment of the children: loopback-only Cyclone DDS unless the user set CYCLONEDDS_URI."""
    env = dict(os.environ)
    if not env.get("CYCLONEDDS_URI"):
        env["CYCLONEDDS_URI"] = write_loopback_config(out / "cyclonedds.xml")
    src = str(REPO / "src")
    if (REPO / "src" / "mal_planner").is_dir():
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [src, env.get("PYTHONPATH", "")]))
    return env


class Launcher:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.out = Path(args.out)
        self.stop_requested = threading.Event()
        self.children: dict[str, Child] = {}
        self.respawns = 0

    def _start(self, name: str, module_args: list[str], env: dict[str, str]) -> Child:
        child = Child(name, module_args, env, self.out / "logs")
        self.children[name] = child
        return child

    def _wait_ready(self, child: Child, timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while not child.ready.wait(0.1):
            if self.stop_requested.is_set() or time.monotonic() > deadline:
                return False
        return child.running()

    def check_inputs(self, scenario: str, params: str, bag: Path | None) -> str | None:
        """None when the inputs are usable, else a one-line reason (checked before anything starts)."""
        a = self.args
        if a.respawn_max < 1:
            return f"--respawn-max: must be at least 1 (got {a.respawn_max})"
        if a.respawn_delay < 0:
            return f"--respawn-delay: must be >= 0 s (got {a.respawn_delay:g})"
        if bag is not None and bag.exists():
            return f"{bag} exists already; remove it or choose another --record"
        if a.replay is not None:
            from mal_planner.ros.bagio import BagError, open_reader

            try:
                open_reader(a.replay).close()
            except BagError as exc:
                return f"--replay: {exc}"
        from mal_planner.scenario import ScenarioError, load_scenario

        try:
            load_scenario(scenario)
        except ScenarioError as exc:
            return f"--scenario: {' '.join(str(exc).split())}"
        from mal_planner.ros.transport import load_params_file

        try:
            load_params_file(params, "planner")
        except Exception as exc:  # OSError, YAML errors
            return f"--params: cannot read {params}: {' '.join(str(exc).split())}"
        return None

    def run(self) -> int:
        a = self.args
        scenario = a.scenario or _default("scenarios/thesis.yaml")
        params = a.params or _default("config/planner.params.yaml")
        bag = None if a.no_record else Path(a.record) if a.record else self.out / "bag"
        if (error := self.check_inputs(scenario, params, bag)) is not None:
            print(f"launch: {error}", file=sys.stderr, flush=True)
            return 2
        self.out.mkdir(parents=True, exist_ok=True)
        (self.out / "logs").mkdir(exist_ok=True)
        (self.out / STATUS_FILE).unlink(missing_ok=True)
        env = child_env(self.out)
        finite = not a.keep_running and (a.replay is not None or a.duration > 0 or a.closed_loop)
        if a.closed_loop:
            params = write_closed_loop_params(params, scenario, self.out, a.noise_m, a.sim_rate / a.sim_speed)
        print(f"launch: scenario {scenario}, params {params}, out {self.out}, record {bag or 'off'}, "
              f"CYCLONEDDS_URI {env['CYCLONEDDS_URI']}, ROS_DOMAIN_ID {env.get('ROS_DOMAIN_ID', '0')}", flush=True)
        if bag is not None:
            rec = self._start("recorder", ["mal_planner.ros.record", str(bag), "--scenario", scenario], env)
            if not self._wait_ready(rec):
                return self._shutdown(failed="the recorder did not start")
        planner = self._start("planner", ["mal_planner.ros.planner_node", "--scenario", scenario, "--params", params,
                                          "--out", str(self.out)], env)
        if not self._wait_ready(planner):
            return self._shutdown(failed="the planner did not start")
        if a.replay:
            source = self._start("replay", ["mal_planner.ros.replay", a.replay, "--rate", str(a.rate),
                                            "--wait-for-subscribers", "10", *(["--restamp"] if a.restamp else [])],
                                 env)
        elif a.closed_loop:
            source = self._start("radar_sim", ["mal_planner.ros.radar_sim", "--scenario", scenario, "--rate",
                                               str(a.sim_rate), "--speed", str(a.sim_speed), "--clock",
                                               "--wait-for-plan", str(a.timeout), "--until-landed", "--gust-kt",
                                               str(a.gust_kt), "--noise-m", str(a.noise_m), "--seed", "0",
                                               "--topics", "shared", "--out", str(self.out)], env)
        else:
            source = self._start("radar_sim", ["mal_planner.ros.radar_sim", "--scenario", scenario, "--rate",
                                               str(a.sim_rate), "--duration", str(a.duration)], env)
        return self._supervise(source, finite)

    def _supervise(self, source: Child, finite: bool) -> int:
        source_done_at: float | None = None
        idle_since: float | None = None
        while not self.stop_requested.wait(0.2):
            for name, child in list(self.children.items()):
                if child is source or child.running():
                    continue
                if not self._may_respawn(child, finite and source_done_at is not None):
                    again = f" (respawned {self.respawns} time(s))" if self.respawns else ""
                    return self._shutdown(failed=f"{name} {exit_text(child.proc.returncode)}{again}")
                self._respawn(child)
            if source_done_at is None and not source.running():
                if source.proc.returncode != 0:
                    return self._shutdown(failed=f"{source.name} {exit_text(source.proc.returncode)}")
                source_done_at = time.monotonic()
                print(f"launch: {source.name} finished", flush=True)
            if not finite or source_done_at is None:
                continue
            status = read_status(self.out)
            done = bool(status and status["attempts"] >= 1 and not status["planning"] and not status["pending"])
            idle_since = (idle_since or time.monotonic()) if done else None
            if status and idle_since is not None and time.monotonic() - idle_since >= 1.0:
                if status["plans"] < 1:
                    return self._shutdown(failed=f"the planner published no plan: {status['last_error']}")
                return self._shutdown(status=status)
            if time.monotonic() - source_done_at > self.args.timeout:
                return self._shutdown(failed=f"no plan within {self.args.timeout:.0f} s after the radar ended")
        return self._shutdown(status=read_status(self.out), interrupted=True)

    def _may_respawn(self, child: Child, source_ended: bool) -> bool:
        """Whether a child that ended unasked is started again (``--respawn``, attempts left, radar to come)."""
        return (self.args.respawn and child.name in RESPAWNABLE and self.respawns < self.args.respawn_max
                and not source_ended)

    def _respawn(self, child: Child) -> None:
        """Start ``child`` again with its arguments after ``--respawn-delay``; its log goes on in the same file.
        Runs on the main thread: PR_SET_PDEATHSIG fires when the thread that started a child ends."""
        code = child.proc.returncode
        child.stop()  # reaped already: joins the output pump, closes the log
        if self.stop_requested.wait(self.args.respawn_delay):
            return  # stopping: the loop shuts down
        self.respawns += 1
        if child.name == "planner":  # the launcher waits for the new planner's status, not the dead one's
            (self.out / STATUS_FILE).unlink(missing_ok=True)
        new = Child(child.name, child.args, child.env, child.log_dir, append=True)
        self.children[child.name] = new
        print(f"launch: {child.name} {exit_text(code)}: respawned as pid {new.proc.pid} after "
              f"{self.args.respawn_delay:g} s (attempt {self.respawns} of {self.args.respawn_max})", flush=True)

    def _shutdown(self, failed: str | None = None, status: dict[str, Any] | None = None,
                  interrupted: bool = False) -> int:
        """Stop the source, then the planner, the recorder last; the launcher's exit code."""
        if failed:
            print(f"launch: FAILED: {failed}", flush=True)
        codes: dict[str, int] = {}
        for name in ("replay", "radar_sim", "planner", "recorder"):
            if name in self.children:
                codes[name] = self.children[name].stop(signal.SIGINT if name in ("replay", "radar_sim")
                                                       else signal.SIGTERM)
        bad = {n: c for n, c in codes.items() if c not in (0, -signal.SIGINT, -signal.SIGTERM)}
        if bad:
            print("launch: children failed: " + ", ".join(f"{n} {exit_text(c)}" for n, c in bad.items()), flush=True)
        if status and status.get("aircraft"):
            print(f"launch: {status['plans']} plan(s); last plan:\n{summary_table(status)}", flush=True)
            outputs = sorted(p.name for p in self.out.iterdir() if p.suffix in (".json", ".png", ".md"))
            print(f"launch: outputs in {self.out}: {', '.join(outputs)}", flush=True)
        if failed or bad:
            return 1
        return 130 if interrupted and not status else 0


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    launcher = Launcher(args)

    def on_signal(signum: int, _frame: Any) -> None:
        print(f"launch: {signal.Signals(signum).name}: stopping", flush=True)
        launcher.stop_requested.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    return launcher.run()


if __name__ == "__main__":
    sys.exit(main())
