"""ow_viz: making the stack visible in RViz and in bag viewers (Foxglove, Lichtblick)."""
