"""Knowledge-based grasp planner: preshape sweeps in PyBullet, Ferrari-Canny
epsilon, reachability, and a ranked SQLite grasp database."""

__version__ = "0.1.0"
