"""Bring-your-own detectors in the YOLOv8/YOLO11 ONNX layout, run with onnxruntime (`avsim[onnx]`)."""
