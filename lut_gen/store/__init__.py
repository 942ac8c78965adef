"""Tables on disk: EXR files with their headers, the manifest of a bake, atomic writes and
directory locks, and the per-user bake cache."""
from . import atomic, cache, dir_lock, exr_header, exr_min, exr_read, exr_write, manifest, png  # noqa: F401
