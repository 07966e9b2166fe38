"""Training: the losses of the paper's Section 3.4, the staged schedule, and the `hkpd-train`
loop."""
