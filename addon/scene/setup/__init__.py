"""Set Up Scene: check the scene, then wire the world sky, the terrain materials, the drivers
and the compositor passes (and unwire them, restoring what the scene had)."""
