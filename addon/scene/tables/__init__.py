"""The baked tables as Blender images: loading and verifying them, packing them into the .blend,
and what the per-frame code needs of the bake a scene is wired to (wired_bake)."""
