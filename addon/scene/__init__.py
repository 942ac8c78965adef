"""The add-on's work on a scene, by when it runs: setup/ (Set Up Scene: wire the world, the
terrain materials and the compositor), frame/ (before each frame: the frame's camera and sun,
shadow maps, epipolar tables, lighting panoramas, light adaptation) and tables/ (the baked tables
as Blender images). names.py holds every name the add-on gives to something in a .blend."""
