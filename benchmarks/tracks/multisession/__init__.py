"""The multisession track's scoring (seeds/000 Exp B-C): ``metrics``, pure functions over point
sets. The track itself (world, episodes, registration) is built elsewhere (issue 28)."""
