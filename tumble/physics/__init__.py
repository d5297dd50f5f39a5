"""Physics: bodies and shapes, rotations, linear theory and the exact torque-free solution (numpy and the
closed-form kernels; no ensembles, no files)."""
