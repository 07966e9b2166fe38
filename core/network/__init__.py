"""The distribution-prediction network: a ResNet-style backbone over the proxy and independent or
hierarchical matrix-Fisher pose heads, plus shape, global-rotation and camera heads."""
