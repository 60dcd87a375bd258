"""scripts/mc_bound.py's block-shift oracle (docs/analysis.md, "What the texture cannot show")."""

from __future__ import annotations

import numpy as np

from ..scripts import load_script

mc_bound = load_script("scripts/mc_bound.py")


def test_blocks_moved_within_reach_are_found_and_beyond_it_are_not():
    rng = np.random.default_rng(1)
    source = rng.uniform(0, 255, (32, 48, 3))
    mask = np.ones((32, 48), dtype=bool)
    mask[:, :8] = False  # left out of the measure
    # every 8x8 block of the target is the source shifted by its own amount
    shifts = [(1, -2), (0, 3), (-3, 0), (2, 2), (-1, 1), (3, -3)]
    target = np.empty_like(source)
    for b, (r, c) in enumerate((r, c) for r in range(0, 32, 8) for c in range(0, 48, 8)):
        dy, dx = shifts[b % len(shifts)]
        target[r : r + 8, c : c + 8] = np.roll(source, (dy, dx), axis=(0, 1))[r : r + 8, c : c + 8]
    sse, pixels = mc_bound.block_shifted_sse(target, source, mask, block=8, reach=3)
    assert sse == 0.0 and pixels == mask.sum()
    plain = float((((target - source) ** 2).sum(-1) * mask).sum())
    assert plain > 0
    # with a reach of 1 the blocks moved by 2 or 3 are not found
    sse_1, _ = mc_bound.block_shifted_sse(target, source, mask, block=8, reach=1)
    assert 0 < sse_1 < plain
    # pixels outside the mask never count
    noisy = target.copy()
    noisy[:, :8] += 100.0
    assert mc_bound.block_shifted_sse(noisy, source, mask, block=8, reach=3)[0] == 0.0


def test_a_bad_video_is_a_clear_error(tmp_path, capsys):
    missing = tmp_path / "nope.mp4"
    assert mc_bound.main([str(missing)]) == 2
    err = capsys.readouterr().err
    assert "nope.mp4" in err and "Traceback" not in err
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video")
    assert mc_bound.main([str(broken)]) == 2
    assert "broken.mp4" in capsys.readouterr().err
