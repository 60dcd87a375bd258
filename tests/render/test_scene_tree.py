"""pyrender's scene graph without networkx (`vtts.render.pyrender_adapter.SceneTree`) behaves
as before."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.render import pyrender_adapter as adapter


def _translation(x: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 3] = x
    return m


def test_poses_compose_along_the_tree_and_removal_takes_the_subtree():
    pr = adapter.load_pyrender()
    scene = pr.Scene()
    assert isinstance(scene._digraph, adapter.SceneTree)
    top = pr.Node(matrix=_translation(1.0))
    scene.add_node(top)
    mid = pr.Node(matrix=_translation(2.0))
    scene.add_node(mid, parent_node=top)
    leaf = pr.Node(matrix=_translation(4.0))
    scene.add_node(leaf, parent_node=mid)
    assert scene.get_pose(leaf)[0, 3] == 7.0
    assert scene.get_pose(mid)[0, 3] == 3.0
    scene.set_pose(top, _translation(10.0))
    assert scene.get_pose(leaf)[0, 3] == 16.0
    scene.remove_node(mid)
    assert leaf not in scene.nodes and mid not in scene.nodes
    assert scene.get_pose(top)[0, 3] == 10.0
    with pytest.raises(ValueError):
        scene.get_pose(leaf)


def test_shortest_path_walks_up_to_the_target():
    tree = adapter.SceneTree()
    tree.add_edge("a", "b")
    tree.add_edge("b", "world")
    assert adapter.SceneTrees.shortest_path(tree, "a", "world") == ["a", "b", "world"]
    tree.remove_node("b")
    assert list(tree.neighbors("a")) == []
    with pytest.raises(ValueError, match="no path"):
        adapter.SceneTrees.shortest_path(tree, "a", "world")
