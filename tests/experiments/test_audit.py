import numpy as np

from fog_gym.experiments.audit import audit_frame
from fog_gym.cli import main


def test_audit_counts_precision_and_recall_by_distance():
    sem = np.zeros((100, 100), np.uint8)
    depth = np.full((100, 100), 500.0, np.float32)
    sem[10:30, 10:30] = 14  # a 400 px car at 15 m
    depth[10:30, 10:30] = 15.0
    sem[60:80, 60:80] = 15  # a 400 px truck at 50 m
    depth[60:80, 60:80] = 50.0
    boxes = np.array([[[10, 10], [29, 29]], [[85, 85], [99, 99]]])  # one tight box, one on empty road
    r = audit_frame(sem, depth, boxes)
    assert (r["boxes"], r["precise"], r["blobs"]) == (2, 1, 2)
    assert r["bins_total"].tolist() == [1, 0, 1, 0] and r["bins_found"].tolist() == [1, 0, 0, 0]


def test_audit_command_writes_markdown_and_png(tmp_path, capsys):
    main(["audit", "--frames", "12", "--resolution", "64x48", "--out", str(tmp_path)])
    text = (tmp_path / "audit.md").read_text()
    assert "| `lidar` |" in text and "| `camera` |" in text
    assert (tmp_path / "audit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
