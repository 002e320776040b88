"""Presenting results: pictures of grasps and the calibration report."""
