"""Every file format of export and import: importing this module imports
each format module, and each registers its writer and reader
(:mod:`planner.datasets.registry`). A new format is one module that ends
with its :func:`~planner.datasets.registry.register` call, named here."""

from __future__ import annotations

from planner.datasets import acronym, dexgraspnet, graspgen, moveit, registry, table

#: The format modules, each registered on import.
MODULES = (acronym, graspgen, dexgraspnet, moveit, table)
#: Formats with a writer (``grasp export``) and with a reader (``grasp import``), sorted.
EXPORT_FORMATS = registry.export_formats()
IMPORT_FORMATS = registry.import_formats()

writer = registry.writer
reader = registry.reader
