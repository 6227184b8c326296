"""Where the cutter touches the part: cutters, the mesh and its search, normals from the path, samples."""
