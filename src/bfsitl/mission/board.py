"""A flight controller on a serial port as a vehicle: RC by MSP, wall time, no truth.

:class:`BoardVehicle` is what :func:`bfsitl.connect` returns: the same
:class:`~bfsitl.mission.vehicle.Vehicle` an :class:`~bfsitl.autopilot.Autopilot` flies in the
simulator, reached over ``serial://`` (or ``tcp://``) instead.  On start it

1. opens the link and asks the FC who it is (MSP_API_VERSION, MSP_FC_VERSION, and whether
   MSP_RAW_GPS answers: position control needs a GPS);
2. checks that the receiver is MSP (feature ``RX_MSP``): otherwise MSP_SET_RAW_RC is
   acknowledged and ignored, and the autopilot would fly nothing (docs/real-board.md says how
   to switch it, which takes a reboot);
3. measures its accelerometer's scale at rest (:mod:`bfsitl.backend.board`);
4. provisions the autopilot's mode ranges (ARM on AUX1, ANGLE on AUX2) when they differ,
   saved without a reboot;
5. starts :class:`~bfsitl.fc.rc_link.MspRcLink` (25 Hz by default) with the sticks at disarm.

The FC's own serial budget is the limit here (``docs/real-board.md``, section 4): every
control step costs one MSP_MULTIPLE_MSP round trip and, in position control, one MSP_RAW_GPS,
besides the RC frames.  At the default ``serial_update_rate_hz`` (100) that is about 30 steps
per second; the autopilot's loop runs as fast as it can below its rate and never catches up
in bursts.

Closing sends disarm and low throttle (three times), then closes the link.  If the program
dies hard the board sees no RC for 150 ms: RXLOSS, then failsafe (a board does not hold the
last sticks, unlike a SITL on UDP).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Self

from bfsitl.backend.board import BoardBackend
from bfsitl.errors import BoardSetupError
from bfsitl.fc.firmware_detect import detect_profile
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.provisioning import Profile, ProvisionResult, provision
from bfsitl.fc.rc_link import DEFAULT_MSP_RATE_HZ, MspRcLink
from bfsitl.link import Link, open_link
from bfsitl.mission.vehicle import DEFAULT_ARM_TIMEOUT_S, Progress, Vehicle
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import FirmwareProfile

#: How long an MSP request may take on a board: a UART at 115200 baud plus one serial tick.
BOARD_MSP_TIMEOUT_S = 1.0


class BoardVehicle(Vehicle):
    """A flight controller reached at ``uri``, flown with RC by MSP (see the module
    docstring).  Nothing is opened when it is made: :meth:`start` (or entering the ``with``
    block) does.

    Args:
        uri: The board's link: ``serial:///dev/ttyACM0?baud=115200`` or ``tcp://HOST:PORT``.
        profile: The mode ranges (and CLI lines) to provision; None flies with what the
            board holds.
        rc_rate_hz: RC frames per second sent by MSP (MSP_SET_RAW_RC).
        timeout_s: Seconds an MSP request may take before it is retried or given up.
        arm_timeout_s: Seconds :meth:`arm` waits by default for the FC to arm.
        angle_mode: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
        progress: Called with one line of text at each step of the start.
        link_opener: Opens the link from ``uri`` (called with ``timeout_s=``); None is
            :func:`~bfsitl.link.open_link`.  Tests pass anything that speaks MSP.
    """

    #: What the default serial task (100 Hz) leaves room for next to RC and the GPS.
    control_rate_hz = 25.0

    def __init__(
        self,
        uri: str,
        *,
        profile: Profile | None = None,
        rc_rate_hz: float = DEFAULT_MSP_RATE_HZ,
        timeout_s: float = BOARD_MSP_TIMEOUT_S,
        arm_timeout_s: float = DEFAULT_ARM_TIMEOUT_S,
        angle_mode: bool = True,
        progress: Progress | None = None,
        link_opener: Callable[..., Link] | None = None,
    ) -> None:
        super().__init__(progress=progress, arm_timeout_s=arm_timeout_s, angle_mode=angle_mode)
        self.uri = uri
        #: Opens the link to the board from ``uri`` (``timeout_s=``): a serial port or a TCP
        #: socket by default (:func:`~bfsitl.link.open_link`), anything that speaks MSP in
        #: tests.
        self._open_link = link_opener if link_opener is not None else open_link
        self.profile = profile
        self.rc_rate_hz = rc_rate_hz
        self.timeout_s = timeout_s
        self.provisioned: ProvisionResult | None = None
        self._client: MspClient | None = None
        self._firmware: FirmwareProfile | None = None
        self._has_gps = False

    def start(self) -> Self:
        """Connect, check, provision, start RC; a started vehicle is returned as it is.

        Returns:
            This vehicle, started.

        Raises:
            LinkError: The link cannot be opened.
            MspError: The board does not answer MSP.
            BoardSetupError: Its receiver is not MSP, or a setting needs a reboot first.
            ProvisioningError: The profile could not be written or read back.
        """
        if self._client is not None:
            return self
        try:
            link = self._open_link(self.uri, timeout_s=self.timeout_s)
            self._stack.callback(link.close)
            client = MspClient(link, timeout_s=self.timeout_s)
            self._client = client
            # A board's build has no record, so ask the FC whether it has a GPS; the profile
            # carries the answer (the summary and the fault catalog read it there).
            self._firmware = detect_profile(client, probe_gps=True)
            self._has_gps = self._firmware.has_gps
            # Measured before arming, while the board stands still.
            self.backend = BoardBackend.measured(lambda: client.get(msg.RawImu).acc_raw)
            self.clock = self.backend.clock
            self._progress(
                f"connected to {self.uri}: {self._firmware.name}"
                + ("" if self._has_gps else ", no GPS (altitude only)")
                + f", accelerometer {self.backend.imu.acc_1g_lsb:g} LSB per g"
            )
            self._check_receiver(client)
            if self.profile is not None:
                self.provisioned = provision(client, self.profile, reboot=self._no_reboot)
                self._progress(
                    "provisioned: "
                    + (
                        "written and saved"
                        if self.provisioned.changed
                        else "already configured, nothing written"
                    )
                )
            self._start_rc(MspRcLink(client, rate_hz=self.rc_rate_hz))
        except BaseException:
            self.close()
            raise
        return self

    @staticmethod
    def _check_receiver(client: MspClient) -> None:
        features = client.get(msg.FeatureConfig).features
        if "RX_MSP" not in features:
            raise BoardSetupError(
                f"the FC's receiver is not MSP (features: {', '.join(features) or 'none'}): "
                f"MSP_SET_RAW_RC would be acknowledged and ignored. Switch the receiver to MSP "
                f"(the Configurator's Receiver tab, or the feature mask over MSP as "
                f"docs/real-board.md shows), save, reboot, and connect again"
            )

    @staticmethod
    def _no_reboot() -> None:
        raise BoardSetupError(
            "the settings were saved but take effect only after a reboot: power-cycle or "
            "reboot the board (`bfsitl cli --uri URI reboot`), then connect again"
        )

    # -- the Vehicle parts ----------------------------------------------------------------------
    @property
    def client(self) -> MspClient:
        if self._client is None:
            return super().client
        return self._client

    @property
    def has_gps(self) -> bool:
        return self._has_gps

    @property
    def firmware(self) -> FirmwareProfile | None:
        return self._firmware
