"""Each agent's actor alone, for decentralised execution: one self-contained file per agent (ONNX or TorchScript) and a
manifest.

Centralised training, decentralised execution: at deployment each agent runs on its own, with its own observation.
:func:`export_actors` writes, for every agent, a network that takes that agent's observation (``[batch, obs_size]``,
float32, as the env gives it) and returns its action in the env's units: a continuous agent's action rescaled from the
policy's [-1, 1] to its ``Box`` (what ``model.predict(..., deterministic=True)`` gives for its slice), a discrete agent's
action index (int64). Each file holds its weights (no ``.onnx.data`` beside it): copy it alone to the agent's machine.
An observation normalisation (``VecNormalize``) stays outside: normalise before calling it.
"""

import json
import logging
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import LAYER_NORM_EPS, AgentEnsembleMLP
from sb3_maddpg.common.package_warnings import SB3MADDPGDeprecationWarning
from sb3_maddpg.common.user_code import user_stacklevel
from sb3_maddpg.version import __version__

FORMATS = {"onnx": ".onnx", "torchscript": ".pt"}
"""Export formats and their file suffixes."""
MANIFEST = "manifest.json"
"""The manifest's file name in the export directory."""
ONNX_OPSET = 18
"""The ONNX operator set of the exported files (onnxruntime 1.14 and newer run it): torch's exporter writes 18 itself,
so that no version conversion (which it warns may fail) is needed."""
ABOUT = {
    "onnx": (
        "Each agent's <agent_id>.onnx is its actor alone, self-contained (its weights inside, no .onnx.data file): "
        "copy it alone and run it with onnxruntime.InferenceSession(path). Input 'observation': the agent's own "
        "observation, [batch, observation_size] float32. Output 'action': its action in the env's units (a Box "
        "agent's floats, a discrete agent's int64 index). This manifest is for people and tools; no file needs it."
    ),
    "torchscript": (
        "Each agent's <agent_id>.pt is its actor alone, self-contained (its weights inside): copy it alone and load it "
        "with torch.jit.load(path). It takes the agent's own observation, [batch, observation_size] float32, and "
        "returns its action in the env's units (a Box agent's floats, a discrete agent's int64 index). This manifest "
        "is for people and tools; no file needs it."
    ),
}
"""What the files of each format are, in the manifest's ``about``."""
EXPORTER_LOGGER = "torch.onnx._internal.exporter._registration"
"""The logger of torch's ONNX exporter that reports, on every export, each torchvision operator it skips."""


class AgentActor(nn.Module):
    """
    One agent's actor as a standalone network: its layers copied out of the team's actor ensemble, then its action
    in the env's units.

    :param mlp: The team's actor networks.
    :param agent: The agent's index.
    :param layout: The team's layout.
    :param low: The agent's action lower bounds (continuous agents).
    :param high: The agent's action upper bounds (continuous agents).
    """

    low: th.Tensor
    high: th.Tensor

    def __init__(self, mlp: AgentEnsembleMLP, agent: int, layout: AgentLayout, low: th.Tensor, high: th.Tensor) -> None:
        super().__init__()
        member = 0 if mlp.share_parameters else agent
        in_dim, out_dim = layout.obs_sizes[agent], layout.action_sizes[agent]
        layers: list[nn.Module] = []
        norms = mlp.norms
        for index, (weight, bias) in enumerate(zip(mlp.weights, mlp.biases)):
            rows = weight[member, :in_dim] if index == 0 else weight[member]
            columns = slice(None) if index < mlp.n_layers - 1 else slice(0, out_dim)
            linear = nn.Linear(rows.shape[0], rows[:, columns].shape[1])
            with th.no_grad():
                linear.weight.copy_(rows[:, columns].T)
                linear.bias.copy_(bias[member, 0, columns])
            layers.append(linear)
            if index < mlp.n_layers - 1:
                if norms:  # the ensemble's layer normalisation, with this agent's scale and shift
                    norm = nn.LayerNorm(linear.out_features, eps=LAYER_NORM_EPS)
                    with th.no_grad():
                        norm.weight.copy_(norms[index][0][member, 0])
                        norm.bias.copy_(norms[index][1][member, 0])
                    layers.append(norm)
                layers.append(type(mlp.activation)())
        self.net = nn.Sequential(*layers)
        self.discrete = layout.is_discrete(agent)
        self.requires_grad_(False)  # for inference only
        self.register_buffer("low", low.detach().clone().float())
        self.register_buffer("high", high.detach().clone().float())

    def forward(self, observation: th.Tensor) -> th.Tensor:
        """
        :param observation: The agent's own observations, ``[batch, obs_size]``.
        :return: Its actions in the env's units, ``[batch, action_size]`` (a discrete agent: indices ``[batch]``).
        """
        output = self.net(observation)
        if self.discrete:
            return output.argmax(dim=1)
        return self.low + 0.5 * (th.tanh(output) + 1.0) * (self.high - self.low)


def agent_actors(model: Any) -> dict[str, AgentActor]:
    """
    :param model: A :class:`~sb3_maddpg.MADDPG` model (trained or not).
    :return: Each agent's standalone actor, by agent id, on the CPU, in eval mode.
    """
    layout: AgentLayout = model.agent_layout
    low = th.as_tensor(model.action_space.low)
    high = th.as_tensor(model.action_space.high)
    mlp = model.policy.actor.mlp.to("cpu")
    try:
        return {
            agent_id: AgentActor(mlp, i, layout, low[layout.action_slices[i]], high[layout.action_slices[i]]).eval()
            for i, agent_id in enumerate(layout.agent_ids)
        }
    finally:
        model.policy.actor.mlp.to(model.device)


def export_actors(model: Any, directory: str | os.PathLike[str], format: str = "onnx") -> dict[str, Path]:
    """
    Write each agent's actor to ``<directory>/<agent_id><suffix>`` and a manifest, ``<directory>/manifest.json``
    (what the files are, agent ids, each agent's file, observation and action spaces, the format, the package
    version). Each agent's file is self-contained, its weights inside: it runs alone, without the other files, the
    manifest, the package or (ONNX) PyTorch. An observation bound that is infinite is written as ``null``: strict JSON
    has no infinity. The export is quiet: torch's exporter's notices that concern no actor are filtered out.

    :param model: A :class:`~sb3_maddpg.MADDPG` model.
    :param directory: Where to write (created if missing).
    :param format: ``"onnx"`` (input ``observation``, output ``action``; a dynamic batch dimension) or
        ``"torchscript"`` (``torch.jit.load`` it).
    :return: Each agent's file, by agent id.
    """
    if format not in FORMATS:
        raise ValueError(f"format must be one of {sorted(FORMATS)}, got {format!r}.")
    if format == "torchscript":  # once per export, in place of torch's three warnings per agent (see _export_torchscript)
        warnings.warn(
            "export_actors(format='torchscript') traces each actor with torch.jit.trace, which PyTorch deprecates: "
            "use format='onnx' (the default; onnxruntime runs it without PyTorch).",
            SB3MADDPGDeprecationWarning,
            stacklevel=user_stacklevel(),
        )
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    layout: AgentLayout = model.agent_layout
    actors = agent_actors(model)
    files: dict[str, Path] = {}
    entries = []
    for i, (agent_id, actor) in enumerate(actors.items()):
        path = out / f"{agent_id}{FORMATS[format]}"
        example = th.zeros(1, layout.obs_sizes[i])
        if format == "onnx":
            _export_onnx(actor, example, path)
            # A weights file an earlier version wrote beside this one: the new file does not read it, and it misleads.
            path.with_name(path.name + ".data").unlink(missing_ok=True)
        else:
            _export_torchscript(actor, example, path)
        files[agent_id] = path
        action_slice, obs_slice = layout.action_slices[i], layout.obs_slices[i]
        entries.append(
            {
                "agent_id": agent_id,
                "file": path.name,
                "observation_size": layout.obs_sizes[i],
                "observation_slice": [obs_slice.start, obs_slice.stop],
                "observation": {
                    "type": "box",
                    "dtype": str(model.observation_space.dtype),
                    "low": _bounds(model.observation_space.low[obs_slice]),
                    "high": _bounds(model.observation_space.high[obs_slice]),
                },
                "action": (
                    {"type": "discrete", "n": layout.action_sizes[i]}
                    if layout.is_discrete(i)
                    else {
                        "type": "box",
                        "low": model.action_space.low[action_slice].tolist(),
                        "high": model.action_space.high[action_slice].tolist(),
                    }
                ),
            }
        )
    manifest: dict[str, Any] = {
        "format": format,
        "sb3_maddpg_version": __version__,
        "about": ABOUT[format],
        "agents": entries,
    }
    if format == "onnx":
        manifest["onnx"] = {"input": "observation", "output": "action", "opset": ONNX_OPSET, "external_data": False}
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return files


def _bounds(values: np.ndarray) -> list[float | None]:
    """:return: Box bounds as JSON numbers, ``None`` (``null``) for an unbounded one (strict JSON has no infinity)."""
    return [float(value) if np.isfinite(value) else None for value in values.tolist()]


def _export_onnx(actor: AgentActor, example: th.Tensor, path: Path) -> None:
    """Write one actor as ONNX, with a dynamic batch dimension."""
    try:  # torch's exporter needs both; said here with the fix
        import onnx  # noqa: F401
        import onnxscript  # noqa: F401
    except ModuleNotFoundError as error:
        from sb3_maddpg.common.install_hint import extra_install_command

        raise ModuleNotFoundError(
            "export_actors(format='onnx') needs onnx and onnxscript, which are not installed: "
            f"{extra_install_command('export')}, or use format='torchscript'."
        ) from error
    with _quiet_exporter():
        th.onnx.export(
            actor,
            (example,),
            str(path),
            input_names=["observation"],
            output_names=["action"],
            dynamic_shapes={"observation": {0: th.export.Dim("batch")}},
            opset_version=ONNX_OPSET,
            dynamo=True,
            # The weights inside the file: an actor is kilobytes (far from protobuf's 2 GB), and a file that needs a
            # `.onnx.data` beside it fails in onnxruntime when copied alone to the agent's machine.
            external_data=False,
            verbose=False,
        )


def _export_torchscript(actor: AgentActor, example: th.Tensor, path: Path) -> None:
    """Write one actor as TorchScript (its weights inside), without torch's deprecation warnings (export_actors warns once)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"`torch\.jit\.trace(_method)?` is deprecated", category=DeprecationWarning)
        th.jit.trace(actor, example).save(str(path))


class _SkipTorchvisionNotice(logging.Filter):
    """Drops the exporter's "torchvision is not installed. Skipping torchvision::nms" lines (four per export)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("torchvision is not installed")


@contextmanager
def _quiet_exporter() -> Iterator[None]:
    """
    Silence the two notices torch's exporter gives on every export that say nothing about the actor: no option of
    ``torch.onnx.export`` turns them off, so each is filtered by its source and its words, and nothing else is.

    - Its operator registry logs each torchvision operator it skips when torchvision is not installed (an actor uses
      none of them).
    - ``ExportedProgram.run_decompositions`` deep-copies its module call graph, whose pytree specs warn (a
      ``FutureWarning``) that their own ``LeafSpec`` check is deprecated: torch's code, not ours or the user's.
    """
    logger = logging.getLogger(EXPORTER_LOGGER)
    notice = _SkipTorchvisionNotice()
    logger.addFilter(notice)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings(
                "ignore", message=r"`isinstance\(treespec, LeafSpec\)` is deprecated", category=FutureWarning
            )
            yield
    finally:
        logger.removeFilter(notice)
