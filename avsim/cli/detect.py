"""`avsim detect` and `avsim replay`: a perception run outside the closed loop, on image files or on
a ROS bag's camera images, one JSON line per image."""

from __future__ import annotations

import argparse
from pathlib import Path

from avsim.cli.overrides import merge_overrides, parse_set
from avsim.config_owners import DETECT_UNREAD, check_only_perception_keys, check_read_on_images
from avsim.outputs import FILE, add_input_argument, add_output_argument


def _cmd_detect(args: argparse.Namespace) -> int:
    import json

    from avsim.perception.images import detect_images

    from avsim.config import SimConfig, with_overrides

    flags = {"perception": {"kind": args.perception}} if args.perception else {}
    overrides = parse_set(args.set)
    config = with_overrides(SimConfig(), merge_overrides(flags, overrides)).perception
    check_only_perception_keys(overrides, "avsim detect")  # before any image is read
    check_read_on_images(config, overrides.get("perception", {}), "avsim detect", DETECT_UNREAD)
    for record in detect_images(config, [Path(p) for p in args.images]):
        print(json.dumps(record), flush=True)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    import json

    from avsim.metrics import write_text_atomic
    from avsim.recording.ros_replay import replay

    given = parse_set(args.set)
    check_only_perception_keys(given, "avsim replay")  # its perception keys: once the bag is open (`replay`)
    overrides = given.get("perception", {})
    if args.perception:
        overrides = {**overrides, "kind": args.perception}
    lines = (json.dumps(record) for record in replay(args.bag, overrides))
    if args.out is None:
        for line in lines:
            print(line, flush=True)
        return 0
    text = "".join(line + "\n" for line in lines)  # all or nothing: written once every image is done
    write_text_atomic(args.out, text)
    print(f"wrote {text.count(chr(10))} image records to {args.out}")
    return 0


DETECT_HELP = """Run a perception on image files and print one JSON line per image:
{"image", "width", "height", "perception", "detections": [{"class", "confidence", "box_xyxy_px"}]}
with every detection at or above perception.min_confidence, highest first, boxes in the
image's own pixels. The whole image is searched (the closed loop's regions of interest and
its min_box_height_px range limit do not apply).

Images of any size:
  detector  letterboxed into its 640x480 input (aspect kept, grey padding), boxes mapped back; an
            image larger than that is also searched at its own pixels (padded to a multiple of 32;
            slower and memory-hungry for large photos) and the two merged by NMS, unless
            perception.detector_native_pixels=false;
  coco      by perception.coco_input: resize squeezes the whole image to 512x512 as
            @vladmandic/human does (aspect not kept); crop runs the network on the image at
            its own resolution (padded to a multiple of 32; slow and memory-hungry for
            large photos); upscale enlarges it by perception.coco_upscale first;
  yolo      by perception.yolo_input, as coco, but resize squeezes it to the cfg's 416x416
            (YOLOv3-tiny; perception.yolo_cfg/yolo_weights/yolo_names for your own files);
  onnx      letterboxed into the model's own input size (640x640 if it is dynamic);
  ensemble  detector and coco on the same image, each detection with its "source".
perception.purify (jpeg, median) cleans each image before the network sees it.
The oracle needs a simulated scene and cannot run on an image."""


def add_commands(sub) -> None:
    """Add `avsim detect` and `avsim replay` to the subcommands `sub`."""
    detect = sub.add_parser("detect", help="run a perception on image files; one JSON line of detections per image",
                            description=DETECT_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    detect.add_argument("images", nargs="+", metavar="IMAGE",
                        help="image files: PNG, JPEG, BMP, GIF or WebP (the formats whose size is checked before decoding)")
    detect.add_argument("--perception", help="detector (default), coco, yolo, ensemble or onnx")
    detect.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override any config key, e.g. --set perception.coco_input=resize (repeatable)")
    detect.set_defaults(func=_cmd_detect)

    rep_bag = sub.add_parser("replay", help="run a perception over a ROS bag's camera images; one JSON line per image",
                             description="Run a pixel perception over every sensor_msgs/CompressedImage of a ROS bag "
                                         "(.mcap, a ROS 2 bag folder or a ROS 1 .bag; needs avsim[ros]), as the closed "
                                         "loop runs it (region of interest, range limit). One JSON line per image: topic, "
                                         "camera, stamp_ns, width, height, perception, detections. The settings start from "
                                         "the bag's own avsim run, if it is one (docs/ros.md).")
    add_input_argument(rep_bag, "bag", help="the bag: an .mcap file or a bag folder")
    rep_bag.add_argument("--perception", help="detector, coco, ensemble or onnx (default: the bag's own, or detector)")
    rep_bag.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                         help="override a perception key, e.g. --set perception.min_confidence=0.3 (repeatable)")
    add_output_argument(rep_bag, "--out", kind=FILE, help="write the JSON lines to this file instead of printing them")
    rep_bag.set_defaults(func=_cmd_replay)
