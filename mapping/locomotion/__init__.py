"""Locomotion-mode prediction from a depth camera (the ``locomotion`` track).

- :mod:`.config`: the pipelines' configs (stages nested: ``ahc``, ``planes``, ``terrain``,
  ``footprint``, ``tsdf``).
- :mod:`.base`: sensor selection, frames and heel strikes, shared; :mod:`.predict`: the next
  step's footprint and mode.
- :mod:`.pipelines`: the pipelines ``terrain-recon`` (and ``terrain-recon-dvio``) and ``single-frame``.
- :mod:`.own_odometry`: D-VIO inside ``terrain-recon`` (``odometry="dvio"``).
- :mod:`.depth` / :mod:`.body`: depth-image helpers; the calibration's sensor mounts.
"""

from .config import LocomotionConfig, TerrainReconConfig, TerrainReconDvioConfig
from .pipelines import SingleFramePipeline, TerrainReconDvioPipeline, TerrainReconstructionPipeline

__all__ = ["LocomotionConfig", "SingleFramePipeline", "TerrainReconConfig", "TerrainReconDvioConfig",
           "TerrainReconDvioPipeline", "TerrainReconstructionPipeline"]
