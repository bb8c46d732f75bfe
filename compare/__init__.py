"""The paper's theory as formulas, metrics, cross-engine checks and the command line."""
