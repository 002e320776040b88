"""Stage 1, the descriptions: TOML and URDF files parsed once, at the edge,
into frozen specs (hands, preshapes, objects) with errors naming file and
field. Nothing here simulates or measures."""
