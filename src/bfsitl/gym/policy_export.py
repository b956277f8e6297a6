"""A trained Stable-Baselines3 policy as one ONNX file that flies without bfsitl's training
stack: the environment's observation in, the four sticks out.

    export_policy(model, "hover.onnx", limits=StickLimits(), hover_throttle=0.1,
                  control_hz=50.0, mode="angle")

The file holds the whole way from what :mod:`~bfsitl.gym.observation` fills (23 numbers:
the FC's own readings and the targets) to the sticks the environment takes (roll, pitch,
throttle, yaw in -1..1): the fixed observation scaling of :mod:`~bfsitl.gym.scaled`, the policy's
deterministic action (PPO's mean, SAC's and TD3's squashed actor), and the stick limits
about the vehicle's hover throttle.  What the policy was trained at rides in the file's
metadata (:data:`~bfsitl.gym.onnx_policy.METADATA_KEYS`): its control rate, the FC's mode,
the observation's layout.  :class:`~bfsitl.gym.onnx_policy.OnnxPolicy` reads it back with
onnxruntime, without torch.

Why ONNX with onnxruntime: the format every inference runtime reads (onnxruntime on a laptop
or a companion computer, TensorRT, the browser), a runtime of about 80 MB from PyPI against
torch's several hundred, and a measured inference time a fraction of a control period
(``benchmarks/gym.py --policy``).  The exporter is torch's TorchScript one
(``dynamo=False``): it exports these small networks in under a second without onnxscript;
the newer one takes seconds and adds a dependency for the same graph.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from bfsitl.errors import EnvironmentConfigError, ExtraMissingError
from bfsitl.gym.observation import OBSERVATION_SIZE
from bfsitl.gym.onnx_policy import OBSERVATION_LAYOUT, POLICY_FORMAT
from bfsitl.gym.scaled import (
    OBSERVATION_OFFSET,
    OBSERVATION_SCALE,
    SCALED_LIMIT,
    StickLimits,
    scale_observation,
)

try:
    import torch
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ExtraMissingError(
        "exporting a policy needs torch and onnx: pip install torch==2.13.0 'bfsitl[learn]'"
    ) from exc

#: The ONNX operator set written (onnxruntime 1.17 and newer read it).
OPSET = 17


class _Flying(torch.nn.Module):
    """Observation to sticks: scaling, the deterministic action, the stick limits."""

    offset: torch.Tensor
    scale: torch.Tensor
    gain: torch.Tensor
    centre: torch.Tensor

    def __init__(self, model: Any, limits: StickLimits, hover_throttle: float) -> None:
        super().__init__()
        self.policy = model.policy
        self.register_buffer("offset", torch.as_tensor(OBSERVATION_OFFSET))
        self.register_buffer("scale", torch.as_tensor(OBSERVATION_SCALE))
        self.action_size = limits.action_size
        per_action = [limits.tilt_stick, limits.tilt_stick, limits.throttle_span]
        if limits.action_size == 4:
            per_action.append(limits.yaw_stick)
        self.register_buffer("gain", torch.tensor(per_action, dtype=torch.float32))
        centre = [0.0, 0.0, hover_throttle] + ([0.0] if limits.action_size == 4 else [])
        self.register_buffer("centre", torch.tensor(centre, dtype=torch.float32))

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        scaled = torch.clamp((observation - self.offset) / self.scale, -SCALED_LIMIT, SCALED_LIMIT)
        action = torch.clamp(self.policy._predict(scaled, deterministic=True), -1.0, 1.0)
        sticks = torch.clamp(self.centre + action * self.gain, -1.0, 1.0)
        if self.action_size == 3:  # yaw held centred
            sticks = torch.cat([sticks, torch.zeros_like(sticks[:, :1])], dim=1)
        return sticks


def export_policy(
    model: Any,
    path: str | Path,
    *,
    limits: StickLimits,
    hover_throttle: float,
    control_hz: float,
    mode: str = "angle",
    description: str = "",
) -> Path:
    """Write ``model`` (an SB3 PPO, SAC or TD3 trained on :class:`~bfsitl.gym.scaled.ScaledEnv`
    or :class:`~bfsitl.gym.sb3_vector.Sb3VectorEnv` with ``limits``) to ``path``."""
    try:
        import onnx
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ExtraMissingError(
            "exporting a policy needs onnx: pip install 'bfsitl[learn]'"
        ) from exc
    expected = (limits.action_size,)
    if tuple(model.action_space.shape) != expected:
        raise EnvironmentConfigError(
            f"the policy acts with {tuple(model.action_space.shape)} numbers, the stick limits "
            f"take {expected}: give the limits it was trained with"
        )
    if tuple(model.observation_space.shape) != (OBSERVATION_SIZE,):
        raise EnvironmentConfigError(
            f"the policy observes {tuple(model.observation_space.shape)} numbers, this bfsitl "
            f"fills {OBSERVATION_SIZE} (bfsitl.gym.observation): train it again here"
        )
    module = _Flying(model, limits, hover_throttle).eval()
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    # The graph goes to the target first, then comes back with the metadata added.
    with torch.no_grad(), warnings.catch_warnings():
        # The TorchScript exporter is deprecated in favour of the dynamo one (see the
        # module docstring for why it is used): its warning says nothing to act on.
        warnings.simplefilter("ignore")
        torch.onnx.export(
            module,
            (torch.zeros(1, OBSERVATION_SIZE),),
            str(target),
            input_names=["observation"],
            output_names=["sticks"],
            dynamic_axes={"observation": {0: "batch"}, "sticks": {0: "batch"}},
            opset_version=OPSET,
            dynamo=False,
        )
    graph = onnx.load(str(target))
    metadata = {
        "bfsitl.format": POLICY_FORMAT,
        "bfsitl.observation": OBSERVATION_LAYOUT,
        "bfsitl.control_hz": f"{control_hz:g}",
        "bfsitl.mode": mode,
        "bfsitl.description": description,
    }
    for key, value in metadata.items():
        entry = graph.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(graph, str(target))
    return target


def trained_sticks(
    model: Any, observations: np.ndarray, limits: StickLimits, hover_throttle: float
) -> np.ndarray:
    """The sticks ``model`` itself gives for raw ``observations`` (one row each), through
    SB3's ``predict``: what the exported file must reproduce."""
    actions, _state = model.predict(scale_observation(observations), deterministic=True)
    return limits.sticks(np.asarray(actions), hover_throttle)
