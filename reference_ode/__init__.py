"""The reference model: the paper's equations of motion, compiled, and their integrator."""
