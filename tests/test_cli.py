"""The command line as a user meets it: listings, help, scaffolding and one-line errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from frontal3d.cli import main


def test_families_json_lists_built_in_families_with_views_and_subtypes(capsys):
    assert main(["families", "--json"]) == 0
    families = {f["name"]: f for f in json.loads(capsys.readouterr().out)}
    assert families["guitar"]["canonical_view"] == "front"
    assert families["car"]["canonical_view"] == "side"
    assert families["airplane"]["canonical_view"] == "top"
    assert {"classical", "electric"} <= set(families["guitar"]["subtypes"])
    assert {"sedan", "suv", "sports"} <= set(families["car"]["subtypes"])
    assert {"airliner", "fighter", "light"} <= set(families["airplane"]["subtypes"])
    assert set(families["guitar"]["regions"]["classical"]) == {"head", "neck", "body", "bridge", "hole"}
    assert set(families["guitar"]["regions"]["electric"]) == {"head", "neck", "body", "bridge", "pickups", "controls"}
    for family in families.values():
        assert not family["template_errors"]
        for subtype in family["subtypes"]:
            assert family["landmarks"][subtype], f"{family['name']}/{subtype} has no landmarks"


def test_plugins_json_lists_hooks(capsys):
    assert main(["plugins", "--json"]) == 0
    plugins = {p["name"]: p for p in json.loads(capsys.readouterr().out)}
    assert {"frontal3d", "guitar", "car", "airplane"} <= set(plugins)
    assert "frontal3d_template" in plugins["guitar"]["hooks"]
    assert "frontal3d_segment" in plugins["frontal3d"]["hooks"]


def test_help_everywhere(capsys):
    for command in (["--help"], ["reconstruct", "--help"], ["evaluate", "--help"], ["template", "show", "--help"], ["new-family", "--help"]):
        with pytest.raises(SystemExit) as exit_info:
            main(command)
        assert exit_info.value.code == 0
    assert "reconstruct" in capsys.readouterr().out


def _one_line_error(capsys, argv: list[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0
    assert len(err) == 1 and err[0].startswith("frontal3d: error: "), err
    return err[0]


def test_unreadable_image_is_one_line_error_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "photo.jpg"
    bad.write_bytes(b"not an image")
    out = tmp_path / "out"
    message = _one_line_error(capsys, ["reconstruct", str(bad), "--family", "car", "-o", str(out)])
    assert "cannot read image" in message and "photo.jpg" in message
    assert not out.exists()


def test_missing_and_empty_images(tmp_path, capsys):
    assert "no such file" in _one_line_error(capsys, ["reconstruct", str(tmp_path / "nope.png"), "--family", "car"])
    assert "it is a folder" in _one_line_error(capsys, ["reconstruct", str(tmp_path), "--family", "car"])
    empty = tmp_path / "empty.png"
    cv2.imwrite(str(empty), np.full((64, 64, 3), 128, np.uint8))
    assert "empty" in _one_line_error(capsys, ["reconstruct", str(empty), "--family", "car", "-o", str(tmp_path / "o")])
    assert not (tmp_path / "o").exists()


def test_an_output_path_that_cannot_be_a_folder_fails_before_the_work(tmp_path, capsys, monkeypatch):
    import frontal3d.pipeline

    def must_not_run(*args, **kwargs):
        raise AssertionError("reconstructed although the output cannot be written")

    monkeypatch.setattr(frontal3d.pipeline, "reconstruct", must_not_run)
    image = tmp_path / "x.png"
    cv2.imwrite(str(image), np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    a_file = tmp_path / "notes.txt"
    a_file.write_text("keep me")
    assert "is not a folder" in _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "-o", str(a_file)])
    message = _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "-o", str(a_file / "out")])
    assert f"{a_file} is a file, not a folder" in message
    assert a_file.read_text() == "keep me"


def test_every_command_checks_its_output_before_the_work(tmp_path, capsys):
    a_file = tmp_path / "notes.txt"
    a_file.write_text("keep me")
    commands = [["synth", "--family", "car", "-n", "2", "-o", str(a_file)],
                ["train", "frontal", "--data", str(tmp_path / "no_data"), "-o", str(a_file / "model.pt")],
                ["template", "show", "car/sedan", "-o", str(a_file / "sheet.png")],
                ["evaluate-gate", "--family", "car", "--synth", str(tmp_path / "no_data"), "-o", str(a_file)]]
    for command in commands:
        assert "is not a folder" in _one_line_error(capsys, command), command
    assert a_file.read_text() == "keep me"


def test_a_file_system_refusal_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    import errno

    import frontal3d.pipeline

    def disk_full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "out" / "model.glb"))

    monkeypatch.setattr(frontal3d.pipeline, "reconstruct", disk_full)
    image = tmp_path / "x.png"
    cv2.imwrite(str(image), np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    message = _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "-o", str(tmp_path / "out")])
    assert message.endswith("model.glb: No space left on device")


def test_unknown_family_is_one_line_error(tmp_path, capsys):
    image = tmp_path / "x.png"
    cv2.imwrite(str(image), np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    assert "unknown family 'boat'" in _one_line_error(capsys, ["reconstruct", str(image), "--family", "boat"])


def test_empty_user_mask_is_one_line_error(tmp_path, capsys):
    image = tmp_path / "x.png"
    cv2.imwrite(str(image), np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    mask = tmp_path / "m.png"
    cv2.imwrite(str(mask), np.zeros((64, 64), np.uint8))
    assert "is empty" in _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "--mask", str(mask)])


def test_bad_setting_is_one_line_error(tmp_path, capsys):
    image = tmp_path / "x.png"
    cv2.imwrite(str(image), np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8))
    assert "unknown setting 'no_such_key'" in _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "--set", "no_such_key=1"])
    wrong_type = _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "--set", "working_resolution=big"])
    assert "setting 'working_resolution': expected int" in wrong_type
    too_small = _one_line_error(capsys, ["reconstruct", str(image), "--family", "car", "--set", "working_resolution=5"])
    assert "setting 'working_resolution': must be at least 16, got 5" in too_small


def test_scaffolded_family_installs_and_is_listed(tmp_path):
    """new-family writes a package that pip installs and frontal3d then lists and uses."""
    package = tmp_path / "frontal3d-teapot"
    assert main(["new-family", "teapot", "--view", "side", "-o", str(package)]) == 0
    site = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target", str(site), str(package)],
        check=True, capture_output=True,
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    listed = subprocess.run([sys.executable, "-m", "frontal3d", "families", "--json"], env=env, check=True, capture_output=True, text=True, cwd=tmp_path)
    families = {f["name"]: f for f in json.loads(listed.stdout)}
    assert families["teapot"]["canonical_view"] == "side"
    assert families["teapot"]["plugin"] == "teapot"
    tests = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(package / "tests")], env=env, capture_output=True, text=True, cwd=tmp_path)
    assert tests.returncode == 0, tests.stdout + tests.stderr


def test_scaffold_refuses_bad_names_and_existing_folders(tmp_path, capsys):
    assert "family name" in _one_line_error(capsys, ["new-family", "Bad Name", "-o", str(tmp_path / "x")])
    (tmp_path / "exists").mkdir()
    assert "already exists" in _one_line_error(capsys, ["new-family", "mug", "-o", str(tmp_path / "exists")])


def test_many_images_go_on_past_a_bad_one_and_name_it_once(tmp_path, capsys):
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "examples" / "sportscar.png"
    bad = tmp_path / "notes.png"
    bad.write_text("not an image")
    out = tmp_path / "out"
    assert main(["reconstruct", str(bad), str(example), "--family", "car", "-o", str(out)]) == 2
    captured = capsys.readouterr()
    errors = [line for line in (captured.out + captured.err).splitlines() if line.startswith("frontal3d: error:")]
    assert len(errors) == 1 and errors[0].count(str(bad)) == 1, errors
    assert (out / "sportscar" / "model.glb").is_file() and not (out / "notes").exists()


@pytest.mark.filterwarnings("error")  # a warning PIL prints on stderr (corrupt EXIF) fails the test too
def test_a_corrupt_tiff_gives_one_line_not_opencvs_decoder_log(tmp_path, capfd):
    photo = tmp_path / "scan.tif"
    cv2.imwrite(str(photo), np.random.default_rng(1).integers(0, 255, (120, 160, 3), dtype=np.uint8))
    data = photo.read_bytes()
    photo.write_bytes(data[: 2 * len(data) // 3])
    assert main(["reconstruct", str(photo), "--family", "car", "-o", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"frontal3d: error: cannot read image {photo}: "), err
