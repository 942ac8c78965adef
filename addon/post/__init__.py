"""bpy-free post-processing: numpy twins of the compositor passes."""
