"""Pure physical models: thermal radiometry and atmosphere, sky, acoustics, RF, trajectories and the
per-frame timeline. No renderer, no files."""
