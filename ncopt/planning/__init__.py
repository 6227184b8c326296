"""Planning S and F: operations, the per-tool plans, the spindle profile, tool tables and profiles."""
