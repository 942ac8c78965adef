"""Before each frame (and after each interactive change): the frame's camera, sun and settings
(frame_state), the shadow maps, the epipolar tables, the frame-values image, the world-lighting
panoramas, Animate Sun and the light adaptation across frames."""
