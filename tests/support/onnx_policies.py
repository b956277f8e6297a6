"""Hand-written policies as bfsitl policy files: one matrix from the observation to the
sticks (``sticks = observation @ weights + bias``), written with onnx's helpers and the
metadata :func:`bfsitl.gym.policy_export.export_policy` writes, so that onnxruntime runs them
as it runs a trained one.  They make the flying side testable without training."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bfsitl.gym.observation import OBSERVATION_SIZE
from bfsitl.gym.onnx_policy import OBSERVATION_LAYOUT, POLICY_FORMAT


def linear_policy_file(
    path: Path,
    weights: np.ndarray,
    bias: np.ndarray | None = None,
    *,
    control_hz: float = 50.0,
    mode: str = "angle",
    policy_format: str = POLICY_FORMAT,
    layout: str = OBSERVATION_LAYOUT,
) -> Path:
    """Write ``sticks = observation @ weights + bias`` (slots x 4, and 4) to ``path``, its
    observation named ``layout``."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    weights = np.asarray(weights, dtype=np.float32).reshape(-1, 4)
    slots = weights.shape[0]
    bias = np.zeros(4, dtype=np.float32) if bias is None else np.asarray(bias, np.float32)
    graph = helper.make_graph(
        [
            helper.make_node("MatMul", ["observation", "weights"], ["product"]),
            helper.make_node("Add", ["product", "bias"], ["sticks"]),
        ],
        "linear_policy",
        [helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["batch", slots])],
        [helper.make_tensor_value_info("sticks", TensorProto.FLOAT, ["batch", 4])],
        initializer=[
            numpy_helper.from_array(weights, "weights"),
            numpy_helper.from_array(bias, "bias"),
        ],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8  # what onnxruntime of any recent release reads
    for key, value in {
        "bfsitl.format": policy_format,
        "bfsitl.observation": layout,
        "bfsitl.control_hz": f"{control_hz:g}",
        "bfsitl.mode": mode,
        "bfsitl.description": "hand-written: sticks proportional to the target's offset",
    }.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, str(path))
    return path


def go_to_target_weights(
    *,
    gain: float = 0.25,
    damping: float = 0.35,
    climb_gain: float = 0.3,
    climb_damping: float = 0.2,
) -> np.ndarray:
    """Sticks toward the target: pitch forward for a target north, roll right for one east,
    throttle up for one above (each damped by its velocity).  Observation slots 0-2 are
    the target minus the position, 3-5 the velocity (bfsitl.gym.observation); sticks are
    roll, pitch, throttle, yaw."""
    weights = np.zeros((OBSERVATION_SIZE, 4), dtype=np.float32)
    weights[1, 0], weights[4, 0] = gain, -damping  # east offset -> roll right
    weights[0, 1], weights[3, 1] = gain, -damping  # north offset -> pitch forward
    weights[2, 2], weights[5, 2] = climb_gain, -climb_damping  # up offset -> throttle
    return weights
