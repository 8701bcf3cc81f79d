"""Studies: the paper's evaluation (simulated and IPOL), chain comparisons, ADC x rate sweeps, and their plots."""
