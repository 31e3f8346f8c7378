"""cuboidcli.io.inputs: which files of a folder `cuboids fit DIR` fits."""

from __future__ import annotations

import cv2
import numpy as np

from cuboidcli.io.inputs import depth_maps_in, has_images, is_colour_image, photos_in


def _frames_folder(root):
    """A folder as NYU and TUM frames come: photos beside their depth maps, plus files that are neither."""
    root.mkdir()
    rgb = np.full((12, 16, 3), 120, np.uint8)
    cv2.imwrite(str(root / "b_rgb.jpg"), rgb)
    cv2.imwrite(str(root / "a_rgb.PNG"), rgb)
    cv2.imwrite(str(root / "c_rgba.png"), np.full((12, 16, 4), 200, np.uint8))
    cv2.imwrite(str(root / "a_depth.png"), np.full((12, 16), 2000, np.uint16))
    cv2.imwrite(str(root / "grey.png"), np.full((12, 16), 90, np.uint8))
    np.save(root / "c_depth.npy", np.full((12, 16), 2.0, np.float32))
    (root / "cameras.json").write_text("{}")
    (root / "notes.txt").write_text("not a frame")
    (root / "sub.png").mkdir()  # a folder named like an image is no frame
    return root


def test_depth_maps_are_the_depth_files_sorted_by_name_without_the_colour_pngs(tmp_path):
    folder = _frames_folder(tmp_path / "frames")
    maps, left_out = depth_maps_in(folder)
    assert [p.name for p in maps] == ["a_depth.png", "c_depth.npy", "grey.png"]
    assert left_out == 2  # the RGB and the RGBA PNG: the frames' photos


def test_photos_are_the_colour_images_and_the_others_are_counted(tmp_path):
    folder = _frames_folder(tmp_path / "frames")
    photos, left_out = photos_in(folder)
    assert [p.name for p in photos] == ["a_rgb.PNG", "b_rgb.jpg", "c_rgba.png"]
    assert left_out == 2  # the 16-bit depth map and the grey image
    assert is_colour_image(folder / "b_rgb.jpg") and not is_colour_image(folder / "a_depth.png")
    assert not is_colour_image(folder / "notes.txt")  # unreadable as an image


def test_a_folder_without_images_is_no_folder_of_frames(tmp_path):
    folder = _frames_folder(tmp_path / "frames")
    assert has_images(folder)
    rooms = tmp_path / "rooms"
    rooms.mkdir()
    np.save(rooms / "scan.npy", np.zeros((100, 3), np.float32))
    (rooms / "scan.ply").write_text("ply")
    assert not has_images(rooms)
