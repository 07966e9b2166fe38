"""Synthetic training data generated on the fly: poses and shapes -> rendered images ->
augmentations -> proxy representation, in batches on a chosen device."""
