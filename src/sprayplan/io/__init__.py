"""Part readers with validation: meshes (STL, OBJ, PLY, OFF) and point clouds (XYZ, PCD), any of them gzipped."""
