"""The torch device a run trains on: ``mitlc train --device auto|cpu|cuda`` (the run's
``device`` setting, :attr:`mitlc.learn.config.TrainConfig.device`).

``auto`` is CUDA where torch sees a CUDA device, else the CPU; ``cuda`` where torch sees none
is a :class:`DeviceError` (the command line prints it and exits with status 1). Checkpoints
hold CPU tensors whatever the device (:mod:`mitlc.learn.rundir.checkpoint`), so a run trained
on CUDA is evaluated, plotted and resumed on a machine without one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mitlc.errors import MitlcError
from mitlc.learn.names import DEVICES

if TYPE_CHECKING:
    import torch


class DeviceError(MitlcError, ValueError):
    """A device that this machine does not have, or a name that is not one."""


def resolve_device(name: str) -> torch.device:
    """The torch device of the setting ``name`` (``auto``, ``cpu`` or ``cuda``, see the module
    docstring); a :class:`DeviceError` for ``cuda`` without CUDA, or another name, or where
    torch is not installed."""
    try:
        import torch
    except ImportError:
        raise DeviceError(f"--device {name} needs torch: pip install 'mitlc[learn]'") from None
    if name not in DEVICES:
        raise DeviceError(f"--device {name}: expected one of {', '.join(DEVICES)}")
    if name == "cpu":
        return torch.device("cpu")
    if torch.cuda.is_available():
        return torch.device("cuda")
    if name == "cuda":
        raise DeviceError(
            f"--device cuda: torch {torch.__version__} sees no CUDA device on this machine "
            "(a CPU build of torch, or no GPU or driver); use --device cpu or auto"
        )
    return torch.device("cpu")
