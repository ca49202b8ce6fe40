"""Locomotion-mode prediction from a depth camera (the ``locomotion`` track).

- :mod:`.config`: the pipelines' configs (stages nested: ``ahc``, ``planes``, ``terrain``,
  ``footprint``, ``tsdf``).
- :mod:`.base`: sensor selection, frames and heel strikes, shared; :mod:`.predict`: the next
  step's footprint and mode.
- :mod:`.pipelines`: the pipelines ``terrain-recon`` and ``single-frame``.
- :mod:`.depth` / :mod:`.body`: depth-image helpers; the calibration's sensor mounts.
"""

from .config import LocomotionConfig, TerrainReconConfig
from .pipelines import SingleFramePipeline, TerrainReconstructionPipeline

__all__ = ["LocomotionConfig", "SingleFramePipeline", "TerrainReconConfig", "TerrainReconstructionPipeline"]
