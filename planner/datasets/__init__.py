"""Dataset files: each format's writer and reader side by side (ACRONYM,
GraspGen, DexGraspNet, Parquet/CSV tables), the shared grasp columns, and the
export and import of a database."""
