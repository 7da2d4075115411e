"""COCO export (one fog level, the cameras asked for): ``OUT/images/<split>/<CAMERA>/<scene folder>_<index>.png`` and
``OUT/annotations/instances_<split>.json`` per FogDrive split exported, with the categories car (1), truck (2) and
large_vehicle (3; FogDrive's "bigger car": vans, large SUVs, ambulances, buses).

A box is FogDrive's 2D box of the camera (inclusive pixel corners ``[[x0, y0], [x1, y1]]``) as COCO's
``[x0, y0, x1 − x0 + 1, y1 − y0 + 1]``: the pixels it covers, as the project's own COCO evaluation counts them.
Images carry ``camera``, ``sample_token``, ``scene`` and ``fog`` (and ``fog_field``, the field of the exported level,
for a set generated with fog fields); annotations ``vehicle_id``.

The same boxes go out in Ultralytics YOLO's layout beside them: ``labels/<split>/<CAMERA>/<name>.txt`` (class = COCO
id − 1, centre and size normalised by the image size), ``<split>.txt`` image lists (``./images/…``) and
``dataset.yaml`` (``yolo detect train data=<absolute path of OUT>/dataset.yaml``). Each split has its own folders, so
Ultralytics keeps one label cache per split and camera (``labels/<split>/<CAMERA>.cache``) instead of rebuilding a
shared one on every run.
"""

from __future__ import annotations

import json

from fog_gym.dataset.export.common import Sink, Source
from fog_gym.dataset.export.frames import COCO_CATEGORIES, COCO_CATEGORY_ID


def coco_box(box) -> list[float]:
    """FogDrive's inclusive ``[[x0, y0], [x1, y1]]`` → COCO ``[x, y, w, h]``.

    >>> coco_box([[10, 20], [29, 24]])
    [10.0, 20.0, 20.0, 5.0]
    """
    (x0, y0), (x1, y1) = box
    return [float(x0), float(y0), float(x1 - x0 + 1), float(y1 - y0 + 1)]


def write_coco(src: Source, sink: Sink, bar) -> list[str]:
    """Write the export; returns notes for the user. ``bar`` is updated per sample."""
    from fog_gym._version import __version__

    splits = ("train", "val", "test") if src.split == "all" else (src.split,)
    images: dict[str, list] = {s: [] for s in splits}
    annotations: dict[str, list] = {s: [] for s in splits}
    lists: dict[str, list] = {s: [] for s in splits}
    image_id = ann_id = 0
    for scene in src.scenes:
        split, folder = src.split_of(scene), src.folder(scene)
        for k, sample in enumerate(src.samples(scene)):
            token = sample["token"]
            fog_field = src.fog_field(token)
            for cam in src.cameras:
                rel = f"{split}/{cam}/{folder}_{k:06d}.png"  # a folder per split: Ultralytics caches per split
                sink.copy(f"images/{rel}", src.image_path(token, cam))
                width, height = src.image_size(token, cam)
                image_id += 1
                image = {"id": image_id, "file_name": rel, "width": width, "height": height, "camera": cam,
                         "sample_token": token, "scene": scene["name"], "fog": src.fog}  # fmt: skip
                if fog_field is not None:  # a set of fog fields: the field this image was fogged with
                    image["fog_field"] = fog_field
                images[split].append(image)
                b2 = src.boxes_2d(token, cam)
                yolo = []
                for box, vid, cls in zip(b2["bboxes"].tolist(), b2["vehicle_ids"].tolist(), b2["vehicle_class"].tolist()):
                    if cls not in COCO_CATEGORY_ID:
                        continue
                    ann_id += 1
                    bbox = coco_box(box)
                    annotations[split].append({"id": ann_id, "image_id": image_id, "category_id": COCO_CATEGORY_ID[cls],
                                               "bbox": bbox, "area": bbox[2] * bbox[3], "iscrowd": 0,
                                               "vehicle_id": vid})  # fmt: skip
                    yolo.append(yolo_line(COCO_CATEGORY_ID[cls] - 1, bbox, width, height))
                sink.write(f"labels/{rel[:-4]}.txt", "".join(yolo).encode())
                lists[split].append(f"./images/{rel}\n")
            bar.update()
    info = {"description": f"fog-gym FogDrive export, fog={src.fog}, cameras={list(src.cameras)}",
            "version": __version__}  # fmt: skip
    files = {f"annotations/instances_{s}.json": json.dumps({
        "info": info, "licenses": [], "images": images[s], "annotations": annotations[s],
        "categories": list(COCO_CATEGORIES)}).encode() for s in splits}  # fmt: skip
    files.update({f"{s}.txt": "".join(lists[s]).encode() for s in splits})
    names = "".join(f"  {c['id'] - 1}: {c['name']}\n" for c in COCO_CATEGORIES)
    files["dataset.yaml"] = ("# Ultralytics YOLO: yolo detect train data=<absolute path of this file>\n"
                             + "".join(f"{s}: {s}.txt\n" for s in splits) + f"names:\n{names}").encode()  # fmt: skip
    sink.write_all(files)
    return []


def yolo_line(cls: int, bbox: list[float], width: int, height: int) -> str:
    """One YOLO label line: class, box centre and size normalised by the image size.

    >>> yolo_line(0, [10.0, 20.0, 20.0, 10.0], 100, 50).strip()
    '0 0.200000 0.500000 0.200000 0.200000'
    """
    x, y, w, h = bbox
    return f"{cls} {(x + w / 2) / width:.6f} {(y + h / 2) / height:.6f} {w / width:.6f} {h / height:.6f}\n"
