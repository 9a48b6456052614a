"""Surface stages: region selection, target filling and sampling, normals, poses, overlap and compression."""
