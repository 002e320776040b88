"""Geometry of the object and of frames: mesh checks and repair, the prepared
solid with its mass properties (and the mesh cache), rotations and contact
frames (all through ``scipy.spatial.transform``), convex decomposition."""
