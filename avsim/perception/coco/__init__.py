"""COCO CenterNet (MobileNetV3) from @vladmandic/human, ported to PyTorch from its TF.js graph."""
