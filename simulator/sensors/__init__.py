"""What a sensor does to the signal it receives: encodings (counts, 8-bit AGC, sRGB) and, next, the
camera model between the renderer and the files."""
