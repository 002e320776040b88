"""Physical validation of stored grasps: the dynamic shake trial, robust
epsilon under noise, and running both over a database."""
