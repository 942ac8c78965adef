"""Scene-side wiring: LUT images, the Sun lamp and camera, world and terrain materials."""
