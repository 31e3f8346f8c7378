"""Exporters: GLB / PLY / OBJ reloaded with trimesh, overlays and label images against known cuboids."""

from __future__ import annotations

import json
import struct

import cv2
import numpy as np
import pytest
import torch
import trimesh

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export import (
    OPENCV_TO_GLTF,
    FittedData,
    image_paths,
    label_colors,
    node_matrix,
    raycast,
    write,
    write_glb,
    write_obj,
)
from cuboidcli.export.boxmesh import BOX_EDGES, BOX_QUADS, BOX_TRIANGLES, CORNER_SIGNS, SIDE_NORMALS, flat_box
from cuboidcli.export.overlay import colorize_labels, draw_overlay, label_image
from cuboidcli.export.ply import OCCLUDED_RGB, UNASSIGNED_RGB
from cuboidcli.geometry.rotations import axis_angle_to_matrix
from cuboidcli.io.result import FitResult, read_result, write_result

# 64x48 camera whose pixel centres never fall exactly on the test boxes' silhouettes.
CAM = Camera(fx=60.0, fy=60.0, cx=31.5, cy=23.5, width=64, height=48)
WALL_M = 5.0


def _rot(axis_angle) -> np.ndarray:
    return axis_angle_to_matrix(torch.tensor(axis_angle, dtype=torch.float64)).numpy()


def _scene() -> list[Cuboid]:
    """Two boxes seen in the depth map (0, 1) and a phantom box (2) floating in front of the wall."""
    return [
        Cuboid([-0.45, 0.1, 2.0], [0.25, 0.3, 0.2], _rot([0.2, -0.4, 0.1]), inlier_gain=40.0),
        Cuboid([0.5, 0.2, 2.5], [0.3, 0.2, 0.3], _rot([0.0, 0.5, 0.0]), inlier_gain=25.0),
        Cuboid([0.1, -0.6, 1.8], [0.2, 0.15, 0.1], np.eye(3), inlier_gain=9.0),
    ]


def _depth_and_labels(cuboids: list[Cuboid]) -> tuple[np.ndarray, np.ndarray]:
    """Depth map (H, W) of the first two boxes in front of a wall at 5 m, and the expected point labels."""
    seen = raycast(CAM, cuboids[:2])
    depth = np.where(seen.label >= 0, seen.depth_m, WALL_M)
    phantom = raycast(CAM, cuboids[2:]).label >= 0
    labels = np.where(seen.label >= 0, seen.label, np.where(phantom, -2, -1))
    return depth, labels


def _box_distance(points: np.ndarray, cub: Cuboid) -> np.ndarray:
    local = (points - cub.center) @ cub.rotation
    q = np.abs(local) - cub.half_size
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _result(cuboids=None) -> FitResult:
    return FitResult(
        camera=CAM, cuboids=_scene() if cuboids is None else cuboids, settings={"tau_sq_m2": 0.004}
    )


def _fitted(result: FitResult, depth_m=None, rgb=None) -> FittedData:
    return FittedData.of_record(result, depth_m=depth_m, rgb=rgb)


def _glb_json(path) -> dict:
    data = path.read_bytes()
    magic, version, _ = struct.unpack("<III", data[:12])
    assert magic == 0x46546C67 and version == 2  # b"glTF", glTF 2.0
    length, kind = struct.unpack("<II", data[12:20])
    assert kind == 0x4E4F534A  # b"JSON"
    return json.loads(data[20 : 20 + length])


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance from a point of either set to its nearest neighbour in the other set."""
    d = np.linalg.norm(a[:, None] - b[None], axis=2)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


# ---------------------------------------------------------------------------------------------- box topology


def test_box_topology_is_outward_and_complete():
    corners = CORNER_SIGNS * np.array([1.0, 2.0, 3.0])
    for quad, normal in zip(BOX_QUADS, SIDE_NORMALS, strict=True):
        p = corners[quad]
        assert np.allclose(
            np.cross(p[1] - p[0], p[2] - p[0]) / np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0])), normal
        )
        assert np.allclose(p @ normal, np.abs(normal) @ [1.0, 2.0, 3.0])  # all four on that side
    assert BOX_EDGES.shape == (12, 2) and BOX_TRIANGLES.shape == (12, 3)
    lengths = sorted(np.linalg.norm(corners[BOX_EDGES[:, 0]] - corners[BOX_EDGES[:, 1]], axis=1))
    assert np.allclose(lengths, [2.0] * 4 + [4.0] * 4 + [6.0] * 4)
    v, f, n = flat_box([0.5, 1.0, 1.5])
    mesh = trimesh.Trimesh(v, f, process=True)  # merging the 24 vertices gives a closed box
    assert mesh.is_watertight and mesh.volume == pytest.approx(6.0)
    assert np.allclose(n[f[:, 0]], trimesh.Trimesh(v, f, process=False).face_normals)


# ---------------------------------------------------------------------------------------------- GLB


def test_glb_nodes_corners_and_extras_round_trip_through_json(tmp_path):
    write_result(tmp_path / "r.json", _result())
    result = read_result(tmp_path / "r.json")
    path = write_glb(tmp_path / "r.glb", result.cuboids, camera=CAM)
    scene = trimesh.load(path, process=False)
    names = sorted(scene.graph.nodes_geometry)
    assert names == ["object_00", "object_01", "object_02"]
    saved = json.loads((tmp_path / "r.json").read_text())["cuboids"]
    for k, name in enumerate(names):
        transform, geom = scene.graph[name]
        mesh = scene.geometry[geom]
        assert np.linalg.det(transform[:3, :3]) == pytest.approx(1.0)
        world = trimesh.transform_points(mesh.vertices, transform)
        expected = np.asarray(result.cuboids[k].corners() @ np.diag([1.0, -1.0, -1.0]))
        assert _match(world, expected) < 1e-6  # float32 storage
        # corners computed from the JSON's own numbers, converted to glTF by hand
        c, a, r = (np.array(saved[k][key]) for key in ("center", "half_size", "rotation"))
        by_hand = (CORNER_SIGNS * a) @ r.T + c
        by_hand[:, 1:] *= -1.0
        assert _match(world, by_hand) < 1e-6
        # outward normals: every face points away from the box centre
        centre = by_hand.mean(axis=0)
        tri = world[mesh.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert np.all(np.einsum("ij,ij->i", normals, tri.mean(axis=1) - centre) > 0)
        colour = mesh.visual.material.baseColorFactor
        assert tuple(int(v) for v in colour[:3]) == palette_color(k)
    doc = _glb_json(path)
    nodes = {n["name"]: n for n in doc["nodes"]}
    extras = nodes["object_01"]["extras"]
    assert "opencv" in extras["frame"]
    assert np.allclose(extras["center"], saved[1]["center"]) and np.allclose(
        extras["rotation"], saved[1]["rotation"]
    )
    assert np.allclose(extras["quat_wxyz"], saved[1]["quat_wxyz"]) and extras["inlier_gain"] == 25.0
    assert len({n["mesh"] for n in doc["nodes"] if "mesh" in n}) == 3
    assert len({n["material"] for m in doc["meshes"] for n in m["primitives"]}) == 3
    cam = nodes["input_camera"]
    assert "matrix" not in cam and doc["cameras"][cam["camera"]]["perspective"]["yfov"] == pytest.approx(
        2 * np.arctan(24 / 60)
    )


def test_node_matrix_maps_local_box_to_converted_corners():
    cub = _scene()[0]
    m = node_matrix(cub)
    local = CORNER_SIGNS * cub.half_size
    assert np.allclose(local @ m[:3, :3].T + m[:3, 3], cub.corners() @ OPENCV_TO_GLTF.T, atol=1e-12)
    assert np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3)) and np.linalg.det(m[:3, :3]) == pytest.approx(1.0)


def test_glb_with_points_puts_the_cloud_on_the_boxes(tmp_path):
    result = _result()
    depth, _ = _depth_and_labels(result.cuboids)
    rgb = np.zeros((CAM.height, CAM.width, 3), np.uint8)
    rgb[..., 0] = np.arange(CAM.width, dtype=np.uint8)[None, :]
    out = write(_fitted(result, depth, rgb), None, (), with_points=True, paths={"glb": tmp_path / "p.glb"})
    scene = trimesh.load(out["glb"], process=False)
    assert sorted(scene.graph.nodes_geometry) == ["object_00", "object_01", "object_02", "points"]
    transform, geom = scene.graph["points"]
    cloud = scene.geometry[geom]
    assert len(cloud.vertices) == CAM.width * CAM.height
    expected = CAM.backproject(depth).reshape(-1, 3) @ OPENCV_TO_GLTF.T
    assert np.allclose(trimesh.transform_points(cloud.vertices, transform), expected, atol=1e-5)
    assert np.array_equal(np.asarray(cloud.colors)[:, 0], rgb[..., 0].reshape(-1))
    # a point on box 0 lies on the box 0 node's surface in glTF coordinates
    seen = raycast(CAM, result.cuboids[:2])
    v, u = np.argwhere(seen.label == 0)[0]
    p_gltf = expected[v * CAM.width + u]
    m = node_matrix(result.cuboids[0])
    local = (p_gltf - m[:3, 3]) @ m[:3, :3]
    assert np.max(np.abs(local) / result.cuboids[0].half_size) == pytest.approx(1.0, abs=1e-9)


def test_glb_with_points_without_depth_is_refused(tmp_path):
    with pytest.raises(ValueError, match="depth map"):
        write(_fitted(_result()), None, (), with_points=True, paths={"glb": tmp_path / "x.glb"})


# ---------------------------------------------------------------------------------------------- PLY


def test_label_colours():
    cols = label_colors(np.array([0, 1, -1, -2, 17]))
    assert [tuple(c) for c in cols] == [
        palette_color(0),
        palette_color(1),
        UNASSIGNED_RGB,
        OCCLUDED_RGB,
        palette_color(17),
    ]
    with pytest.raises(ValueError):
        label_colors(np.array([-3]))


def test_ply_point_colours_follow_assignment(tmp_path):
    result = _result()
    depth, labels = _depth_and_labels(result.cuboids)
    depth[0, :5] = 0.0  # missing depth is left out
    out = write(_fitted(result, depth), None, (), paths={"ply": tmp_path / "scene_points.ply"})
    assert out["cuboids_ply"] == tmp_path / "scene_cuboids.ply"
    cloud = trimesh.load(out["points_ply"])
    valid = depth.reshape(-1) > 0
    assert len(cloud.vertices) == int(valid.sum()) == CAM.width * CAM.height - 5
    assert np.allclose(cloud.vertices, CAM.backproject(depth).reshape(-1, 3)[valid], atol=1e-5)
    expected = label_colors(labels.reshape(-1)[valid])
    got = np.asarray(cloud.colors)[:, :3]
    assert np.array_equal(got, expected)
    # the scene really exercises every kind of label
    for colour in (palette_color(0), palette_color(1), UNASSIGNED_RGB, OCCLUDED_RGB):
        assert (got == colour).all(axis=1).sum() > 10
    assert b"comment frame opencv" in out["points_ply"].read_bytes()[:200]


def test_cuboid_ply_mesh(tmp_path):
    result = _result()
    depth, _ = _depth_and_labels(result.cuboids)
    out = write(_fitted(result, depth), None, (), point_step=4, paths={"ply": tmp_path / "s.ply"})
    assert len(trimesh.load(out["points_ply"]).vertices) == (CAM.width // 4) * (CAM.height // 4)
    mesh = trimesh.load(out["cuboids_ply"], process=False)
    assert mesh.vertices.shape == (72, 3) and mesh.faces.shape == (36, 3)
    colours = np.asarray(mesh.visual.vertex_colors)[:, :3]
    for k, cub in enumerate(result.cuboids):
        assert _match(mesh.vertices[24 * k : 24 * k + 24], cub.corners()) < 1e-6
        assert (colours[24 * k : 24 * k + 24] == palette_color(k)).all()
    merged = trimesh.load(out["cuboids_ply"])
    assert merged.volume == pytest.approx(sum(c.volume() for c in result.cuboids), rel=1e-5)


def test_ply_needs_depth(tmp_path):
    with pytest.raises(ValueError, match="depth map"):
        write(_fitted(_result()), None, (), paths={"ply": tmp_path / "x.ply"})


# ---------------------------------------------------------------------------------------------- OBJ


def test_obj_objects_and_corners(tmp_path):
    result = _result()
    obj, mtl = write_obj(tmp_path / "s.obj", result.cuboids)
    assert mtl.name == "s.mtl" and "newmtl object_02" in mtl.read_text()
    # object names and their vertex blocks, read from the text
    blocks: dict[str, list] = {}
    for line in obj.read_text().splitlines():
        if line.startswith("o "):
            current = blocks.setdefault(line[2:], [])
        elif line.startswith("v "):
            current.append([float(x) for x in line.split()[1:]])
    assert list(blocks) == ["object_00", "object_01", "object_02"]
    for k, cub in enumerate(result.cuboids):
        assert np.allclose(blocks[f"object_{k:02d}"], cub.corners() @ OPENCV_TO_GLTF.T, atol=1e-6)
    # and a standard loader sees three closed boxes of the right volumes with outward faces
    scene = trimesh.load(obj, split_object=True, group_material=False)
    meshes = [trimesh.Trimesh(g.vertices, g.faces) for g in scene.geometry.values()]  # drop normals, merge
    volumes = sorted(m.volume for m in meshes)  # positive: faces wound outwards
    assert all(m.is_watertight for m in meshes)
    assert np.allclose(volumes, sorted(c.volume() for c in result.cuboids), rtol=1e-4)


# ---------------------------------------------------------------------------------------------- overlay


def test_raycast_axis_aligned_box_covers_expected_pixels():
    box = Cuboid([0.0, 0.0, 2.0], [0.5, 0.25, 0.5], np.eye(3))
    cast = raycast(CAM, [box])
    u, v = CAM.pixel_grid()
    # the front face at z = 1.5 m is the silhouette: |x| <= 0.5, |y| <= 0.25
    expected = (np.abs(u - CAM.cx) <= 60 * 0.5 / 1.5) & (np.abs(v - CAM.cy) <= 60 * 0.25 / 1.5)
    assert np.array_equal(cast.label >= 0, expected)
    assert int(expected.sum()) == 40 * 20
    rows, cols = np.nonzero(cast.label == 0)
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (14, 33, 12, 51)
    assert np.allclose(cast.depth_m[expected], 1.5) and np.all(np.isinf(cast.depth_m[~expected]))
    assert np.allclose(
        cast.shade[expected],
        1.0
        / np.linalg.norm(np.stack([(u - CAM.cx) / 60, (v - CAM.cy) / 60, np.ones_like(u)], -1), axis=-1)[
            expected
        ],
    )


def test_raycast_nearest_box_wins_and_hits_lie_on_surfaces():
    boxes = _scene()
    cast = raycast(CAM, boxes)
    alone = [raycast(CAM, [b]) for b in boxes]
    stacked = np.stack([a.depth_m for a in alone])
    assert np.allclose(cast.depth_m, stacked.min(axis=0))
    hit = np.isfinite(cast.depth_m)
    assert np.array_equal(cast.label[hit], stacked.argmin(axis=0)[hit])
    pts = CAM.backproject(np.where(hit, cast.depth_m, 1.0))[hit]
    for k, b in enumerate(boxes):
        on = cast.label[hit] == k
        assert np.allclose(_box_distance(pts[on], b), 0.0, atol=1e-9)


def test_raycast_from_inside_a_box_sees_its_far_side():
    room = Cuboid([0.0, 0.0, 1.0], [3.0, 2.0, 2.0], np.eye(3))
    cast = raycast(CAM, [room])
    assert (cast.label == 0).all()
    assert cast.depth_m[CAM.height // 2, CAM.width // 2] == pytest.approx(3.0)


def test_label_image_png_round_trip(tmp_path):
    cast = raycast(CAM, _scene())
    img = label_image(cast)
    assert img.dtype == np.uint8 and set(np.unique(img)) == {0, 1, 2, 3}
    cv2.imwrite(str(tmp_path / "l.png"), img)
    back = cv2.imread(str(tmp_path / "l.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(back.astype(np.int64) - 1, cast.label)
    assert label_image(np.full((2, 2), 300)).dtype == np.uint16
    colour = colorize_labels(cast.label)
    assert tuple(colour[cast.label == 1][0]) == palette_color(1) and tuple(colour[cast.label == -1][0]) == (
        0,
        0,
        0,
    )


def test_overlay_tints_the_cuboid_and_hides_back_edges():
    box = Cuboid([0.0, 0.0, 2.0], [0.5, 0.25, 0.5], np.eye(3))
    bg = np.full((CAM.height, CAM.width, 3), 100, np.uint8)
    faces = draw_overlay(bg, CAM, [box], edge_px=0, names=False)
    with_edges = draw_overlay(bg, CAM, [box], edge_px=1, names=False)
    cast = raycast(CAM, [box])
    inside = cast.label == 0
    red = np.array(palette_color(0), float)
    centre = faces[CAM.height // 2, CAM.width // 2].astype(float)
    assert np.allclose(centre, 0.55 * 100 + 0.45 * red * (0.45 + 0.55 * cast.shade[24, 32]), atol=1)
    assert (faces[~inside] == 100).all()
    # back-face edges project to u = cx +- 12 px, inside the front face (cx +- 20 px): hidden
    assert np.array_equal(with_edges[17:31, 17:47], faces[17:31, 17:47])
    # the front silhouette at u = cx + 20 = 51.5 px is drawn
    assert np.abs(with_edges[17:31, 51:53].astype(int) - faces[17:31, 51:53]).max() > 20


def test_overlay_edges_hidden_behind_a_nearer_box():
    far = Cuboid([0.0, 0.0, 4.0], [0.8, 0.6, 0.2], np.eye(3))
    near = Cuboid([0.0, 0.0, 1.5], [0.5, 0.5, 0.1], np.eye(3))  # covers the far box's whole silhouette
    bg = np.zeros((CAM.height, CAM.width, 3), np.uint8)
    behind_camera = Cuboid([0.0, 0.0, -4.0], [0.8, 0.6, 0.2], np.eye(3))  # keeps `near` at palette index 1
    only_near = draw_overlay(bg, CAM, [behind_camera, near], edge_px=1, names=False)
    both = draw_overlay(bg, CAM, [far, near], edge_px=1, names=False)
    assert not np.array_equal(only_near, draw_overlay(bg, CAM, [far], edge_px=1, names=False))
    assert np.array_equal(only_near, both)


def test_write_writes_everything_next_to_the_stem(tmp_path):
    result = _result()
    depth, _ = _depth_and_labels(result.cuboids)
    rgb = np.full((CAM.height, CAM.width, 3), 200, np.uint8)
    written = write(_fitted(result, depth, rgb), tmp_path / "scene.json", ("glb", "ply", "obj", "overlay"))
    names = {k: p.name for k, p in written.items()}
    assert names == {
        "glb": "scene.glb",
        "points_ply": "scene_points.ply",
        "cuboids_ply": "scene_cuboids.ply",
        "obj": "scene.obj",
        "mtl": "scene.mtl",
        "overlay": "scene_overlay.png",
        "labels": "scene_labels.png",
        "labels_color": "scene_labels_color.png",
        "panel": "scene_panel.png",
    }
    assert all(p.is_file() for p in written.values())
    assert sorted(q.name for q in tmp_path.iterdir()) == sorted(names.values())  # no temporary files left
    labels = cv2.imread(str(written["labels"]), cv2.IMREAD_UNCHANGED)
    assert labels.shape == (CAM.height, CAM.width) and labels.dtype == np.uint8
    assert np.array_equal(labels.astype(int) - 1, raycast(CAM, result.cuboids).label)
    panel = cv2.imread(str(written["panel"]))
    assert panel.shape[1] == 4 * CAM.width + 3 * 4 and panel.shape[0] > CAM.height
    assert image_paths(tmp_path / "a_overlay.png")["panel"].name == "a_panel.png"


def test_overlay_size_mismatch_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="64x48"):
        write(
            _fitted(_result(), rgb=np.zeros((10, 10, 3), np.uint8)),
            None,
            (),
            paths={"overlay": tmp_path / "o.png"},
        )


def test_a_result_without_cuboids_still_exports(tmp_path):
    written = write(_fitted(FitResult(camera=CAM, cuboids=[])), tmp_path / "e", ("glb", "obj", "overlay"))
    assert trimesh.load(written["glb"]).graph.nodes_geometry == []
    assert (cv2.imread(str(written["labels"]), cv2.IMREAD_UNCHANGED) == 0).all()
    assert "o cuboid" not in written["obj"].read_text()


def test_point_clouds_of_large_frames_are_subsampled_to_a_vga_frames_size():
    from cuboidcli.export import MAX_CLOUD_PIXELS, cloud_step

    assert cloud_step((480, 640)) == 1 and cloud_step((425, 560)) == 1
    assert cloud_step((3024, 4032)) == 7  # 432 x 576 = 248,832 points; a step of 6 would give 338,688
    assert -(-3024 // 6) * -(-4032 // 6) > MAX_CLOUD_PIXELS >= 432 * 576
    assert cloud_step((3024, 4032), 2) == 2  # an explicit step wins
    with pytest.raises(ValueError, match="at least 1"):
        cloud_step((480, 640), 0)


def test_overlays_name_each_seen_cuboid_by_its_kind():
    """The overlay writes floor_00, object_01, ... in white over the middle of each cuboid it shows, and
    nothing for a cuboid that is out of view."""
    cam = Camera(300.0, 300.0, 159.5, 119.5, 320, 240)
    boxes = [
        Cuboid([0.0, 0.6, 3.0], [1.5, 0.02, 1.5], np.eye(3), kind="floor"),
        Cuboid([0.0, -0.2, 3.0], [0.4, 0.3, 0.3], np.eye(3)),
        Cuboid([0.0, 0.0, -3.0], [0.4, 0.3, 0.3], np.eye(3)),  # behind the camera
    ]
    bg = np.full((240, 320, 3), 40, np.uint8)
    named = draw_overlay(bg, cam, boxes)
    plain = draw_overlay(bg, cam, boxes, names=False)
    text = (named.min(axis=2) > 180) & (plain.max(axis=2) < 180)  # anti-aliased white letters
    rows, cols = np.nonzero(text)
    assert text.sum() > 100
    cast = raycast(cam, boxes)
    # white text lies over both seen boxes (floor below, the box above it), none over the hidden one
    assert (cast.label[rows, cols] == 1).sum() > 20 and (cast.label[rows, cols] == 0).sum() > 20
