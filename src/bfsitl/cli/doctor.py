"""``bfsitl doctor``: is this machine ready to fly, and if not, why?

Checks, each a line with ok / WARN / FAIL and a fix:

1. the SITL binary (where it was found, that it runs);
2. stale SITL processes on the host (they silently share UDP 9003/9004 with a new one);
3. the SITL's ports and the simulator's motor port on the host network;
4. network-namespace isolation (``unshare``);
5. a live probe: an isolated SITL with the embedded physics, provisioned with ARM on AUX1 and
   fed RC; every arming blocker it reports is explained, then it is armed and disarmed.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import BfsitlError
from bfsitl.protocol.arming import ArmingFlagInfo
from bfsitl.sitl.firmware import find_firmware
from bfsitl.sitl.network import unshare_available
from bfsitl.sitl.ports import SIM_UDP_PORTS, SITL_TCP_PORTS, SITL_UDP_PORTS, find_port_holders

#: FC seconds the probe waits for the boot-time blockers (BOOTGRACE is 5 s) to clear.
PROBE_TIMEOUT_S = 12.0


@dataclass(frozen=True, slots=True)
class Finding:
    status: str  # "ok", "WARN" or "FAIL"
    check: str
    detail: str

    def line(self) -> str:
        return f"[{self.status:>4}] {self.check}: {self.detail}"


def add_doctor_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    doctor = sub.add_parser(
        "doctor",
        help="check the firmware, ports and a live probe; explain arming blockers",
        description="Check that this machine can fly: the SITL binary, stale SITL processes, "
        "taken ports, namespace isolation, and a live probe that provisions an "
        "isolated SITL, explains every arming blocker it sees and arms it.",
    )
    doctor.add_argument(
        "--firmware",
        default=None,
        help="SITL binary or cached build name to check (`bfsitl firmware list`)",
    )
    doctor.add_argument("--no-probe", action="store_true", help="skip the live probe")
    doctor.set_defaults(func=cmd_doctor)


def stale_sitl_processes() -> list[tuple[int, str]]:
    """SITL processes of any kind on this machine (all namespaces: pids are shared)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        name = os.path.basename(argv[0].decode(errors="replace")) if argv and argv[0] else ""
        if name.endswith("_SITL") or name.endswith("_SITL.elf"):
            found.append((int(entry.name), name))
    return sorted(found)


def static_checks(firmware: str | None) -> list[Finding]:
    findings = []
    try:
        binary = find_firmware(firmware)
        findings.append(Finding("ok", "firmware", f"{binary.path} (from {binary.source})"))
    except BfsitlError as exc:
        findings.append(Finding("FAIL", "firmware", str(exc)))
    stale = stale_sitl_processes()
    if stale:
        listed = ", ".join(f"pid {pid} ({name})" for pid, name in stale)
        findings.append(
            Finding(
                "WARN",
                "running SITLs",
                f"{listed}. One in the host network shares UDP 9003/9004 with any new SITL there; "
                f"stop it (kill PID) unless you started it on purpose",
            )
        )
    else:
        findings.append(Finding("ok", "running SITLs", "none"))
    holders = find_port_holders(SITL_TCP_PORTS, SITL_UDP_PORTS + SIM_UDP_PORTS[:1])
    if holders:
        findings.append(
            Finding(
                "WARN",
                "host ports",
                "; ".join(h.describe() for h in holders)
                + ". `--start` (isolated) is unaffected; `--no-isolate` and --attach would clash",
            )
        )
    else:
        findings.append(Finding("ok", "host ports", "TCP 5761, UDP 9002-9004 free"))
    if unshare_available():
        findings.append(Finding("ok", "isolation", "unshare found: each SITL gets a namespace"))
    else:
        findings.append(
            Finding(
                "WARN",
                "isolation",
                "unshare missing (apt-get install util-linux): SITLs would share host ports",
            )
        )
    findings.append(physics_check())
    return findings


def physics_check() -> Finding:
    """Whether the embedded physics (C, built once per machine) builds and loads here: without
    it nothing can be flown but Gazebo's physics."""
    from bfsitl.errors import KernelUnavailableError
    from bfsitl.kernel.compiler import kernel_path, load_kernel

    try:
        load_kernel()
    except KernelUnavailableError as exc:
        return Finding("FAIL", "physics", str(exc).splitlines()[0])
    return Finding("ok", "physics", f"built ({kernel_path()})")


def live_probe(firmware: str | None, report: Callable[[str], None]) -> list[Finding]:
    """Start an isolated SITL with physics, provision it, feed RC, explain blockers, arm."""
    from bfsitl.fc.provisioning import provision
    from bfsitl.fc.rc_link import RcCommand, UdpRcLink
    from bfsitl.physics import Simulator
    from bfsitl.sim.bridge import bridged_sitl
    from bfsitl.sim.health import HealthMonitor
    from bfsitl.sitl.process import SitlProcess

    findings = []
    sitl = SitlProcess(firmware, isolate=True, progress=report)
    rc: UdpRcLink | None = None
    try:
        with bridged_sitl(sitl, Simulator()) as bridge:
            assert sitl.client is not None
            client = sitl.client
            # Seen right after boot and physics start: the blockers a user meets first.
            seen = {b.cli_name: b for b in client.status().arming_blockers}
            provision(client)
            rc = UdpRcLink(sitl.network)
            rc.start()
            deadline = time.monotonic() + PROBE_TIMEOUT_S
            blockers: tuple[ArmingFlagInfo, ...] = ()
            while time.monotonic() < deadline:
                blockers = client.status().arming_blockers
                seen.update({b.cli_name: b for b in blockers})
                if not blockers:
                    break
                time.sleep(0.2)
            for name, info in seen.items():
                still = any(b.cli_name == name for b in blockers)
                findings.append(
                    Finding(
                        "FAIL" if still else "ok",
                        f"arming blocker {name}",
                        f"{info.meaning}; fix: {info.fix}"
                        + ("" if still else " (cleared during the probe)"),
                    )
                )
            if not blockers:
                rc.set(RcCommand().with_aux(0, 1800))
                armed = False
                end = time.monotonic() + 3.0
                while not armed and time.monotonic() < end:
                    armed = client.status().armed
                    time.sleep(0.05)
                rc.set(RcCommand())
                findings.append(
                    Finding(
                        "ok" if armed else "FAIL",
                        "arming",
                        "armed and disarmed" if armed else "nothing blocked, yet it did not arm",
                    )
                )
            monitor = HealthMonitor(bridge, client)
            monitor.reset()
            time.sleep(1.5)
            sample = monitor.sample()
            findings.append(
                Finding(
                    "ok" if sample.faithful else "WARN",
                    "simulation health",
                    f"firmware clock / sim time {sample.fc_clock_ratio}, PID cycle "
                    f"{sample.fc_cycle_us} us, {sample.answered_ratio * 100:.1f} % of fdm answered"
                    + (
                        ""
                        if sample.faithful
                        else "; on a busy machine try `bfsitl sim --speed 0.5`"
                    ),
                )
            )
    except BfsitlError as exc:
        findings.append(Finding("FAIL", "live probe", str(exc).splitlines()[0]))
    finally:
        if rc is not None:
            rc.close()
    return findings


def cmd_doctor(args: argparse.Namespace) -> int:
    from bfsitl.cli.target import progress

    findings = static_checks(args.firmware)
    for finding in findings:
        print(finding.line(), flush=True)
    firmware_ok = findings[0].status == "ok"
    if not args.no_probe and firmware_ok:
        for finding in live_probe(args.firmware, progress):
            findings.append(finding)
            print(finding.line(), flush=True)
    failed = [f for f in findings if f.status == "FAIL"]
    print(f"\n{len(failed)} problem(s) found" if failed else "\nready to fly")
    return 1 if failed else 0
