"""A policy from an ONNX file (:func:`~bfsitl.gym.policy_export.export_policy` writes one),
run with onnxruntime: observation in, sticks out, with what it was trained at.

    policy = OnnxPolicy("hover.onnx")
    sticks = policy(observation)          # roll, pitch, throttle, yaw in -1..1
    policy.control_hz, policy.mode        # 50.0, "angle"

Needs onnxruntime only (``pip install 'bfsitl[policy]'``), not torch.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bfsitl.errors import EnvironmentConfigError, ExtraMissingError
from bfsitl.gym.observation import FIRST_LAYOUT_SIZE, OBSERVATION_SIZE

#: Written into every exported file; a file without it is not a bfsitl policy.
POLICY_FORMAT = "bfsitl-policy-1"
#: The observation's layout, named in the file (bfsitl.gym.observation's slots).
OBSERVATION_LAYOUT = f"bfsitl.gym.observation/{OBSERVATION_SIZE}"
#: The layouts a file may name, by the slots its network takes: the first 20 slots mean the
#: same in both, so a policy exported before the next leg's slots is given those.
READABLE_LAYOUTS = {
    OBSERVATION_LAYOUT: OBSERVATION_SIZE,
    f"bfsitl.gym.observation/{FIRST_LAYOUT_SIZE}": FIRST_LAYOUT_SIZE,
}
METADATA_KEYS = (
    "bfsitl.format",
    "bfsitl.observation",
    "bfsitl.control_hz",
    "bfsitl.mode",
    "bfsitl.description",
)


@dataclass(frozen=True)
class PolicyInfo:
    """What an exported policy was trained at (its file's metadata)."""

    control_hz: float
    mode: str
    description: str
    #: How many of the observation's first slots its network takes.
    observation_size: int = OBSERVATION_SIZE


class OnnxPolicy:
    """An exported policy (module docstring); ``__call__`` takes one observation or a batch."""

    def __init__(self, path: str | Path) -> None:
        try:
            import onnxruntime
        except ImportError as exc:  # pragma: no cover - depends on the installation
            raise ExtraMissingError(
                "flying an exported policy needs onnxruntime: pip install 'bfsitl[policy]'"
            ) from exc
        self.path = Path(path)
        if not self.path.is_file():
            raise EnvironmentConfigError(f"{self.path}: no such policy file")
        options = onnxruntime.SessionOptions()
        # One thread: a network this small is done before a second thread would start, and
        # the cores belong to the firmware.
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        try:
            self._session = onnxruntime.InferenceSession(
                str(self.path), options, providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own for a bad file
            raise EnvironmentConfigError(
                f"{self.path}: not an ONNX model onnxruntime can load ({exc})"
            ) from exc
        self.info = _read_info(self.path, self._session.get_modelmeta().custom_metadata_map)

    @property
    def control_hz(self) -> float:
        return self.info.control_hz

    @property
    def mode(self) -> str:
        return self.info.mode

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        values = np.asarray(observation, dtype=np.float32)
        single = values.ndim == 1
        batch = values.reshape(1, -1) if single else values
        if batch.ndim != 2 or batch.shape[1] != OBSERVATION_SIZE:
            raise EnvironmentConfigError(
                f"an observation is {OBSERVATION_SIZE} numbers (bfsitl.gym.observation), got "
                f"shape {values.shape}"
            )
        # A policy of the older layout reads the slots it knew (module docstring of
        # bfsitl.gym.observation).
        taken = np.ascontiguousarray(batch[:, : self.info.observation_size])
        (sticks,) = self._session.run(["sticks"], {"observation": taken})
        result: np.ndarray = sticks[0] if single else sticks
        return result


def _read_info(path: Path, metadata: dict[str, Any]) -> PolicyInfo:
    if metadata.get("bfsitl.format") != POLICY_FORMAT:
        raise EnvironmentConfigError(
            f"{path}: not a bfsitl policy (no {POLICY_FORMAT!r} in its metadata); export one "
            f"with bfsitl.gym.policy_export.export_policy"
        )
    layout = metadata.get("bfsitl.observation")
    if layout not in READABLE_LAYOUTS:
        raise EnvironmentConfigError(
            f"{path}: its observation is {layout!r}, this bfsitl fills {OBSERVATION_LAYOUT!r} "
            f"(and reads {', '.join(repr(name) for name in READABLE_LAYOUTS)}); export the "
            f"policy again with this bfsitl"
        )
    return PolicyInfo(
        control_hz=float(metadata["bfsitl.control_hz"]),
        mode=metadata.get("bfsitl.mode", "angle"),
        description=metadata.get("bfsitl.description", ""),
        observation_size=READABLE_LAYOUTS[layout],
    )
