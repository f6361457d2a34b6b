"""DICOM series (io/dicom.h): series written by these tests with pydicom, converted to
every transfer syntax with GDCM's gdcmconv, read by meshpde.read_volume and by the tool,
each compared voxel for voxel and affine for affine with the same volume as NIfTI."""
import json
import os
import shutil
import struct
import subprocess

import numpy as np
import pytest

import meshpde

if not meshpde.has_medical:
    pytest.skip("built without meshpde::medical", allow_module_level=True)
try:
    import dicom_writer as dw
except ImportError as e:  # python3-pydicom
    if os.environ.get("CI") == "true":
        raise
    pytest.skip(f"python3-pydicom not installed ({e})", allow_module_level=True)

SPACING = (0.7, 0.8, 1.5)
ORIGIN = (10.0, -20.0, 30.0)
SLOPE, INTERCEPT = 2.0, -1024.0


def gdcmconv():
    path = shutil.which("gdcmconv")
    if not path:
        if os.environ.get("CI") == "true":
            pytest.fail("gdcmconv is missing (Debian libgdcm-tools; scripts/install-deps installs it)")
        pytest.skip("gdcmconv not installed (libgdcm-tools)")
    return path


@pytest.fixture(scope="module")
def volume():
    return dw.ct_volume()


@pytest.fixture(scope="module")
def expected(volume):
    return dw.quantized(volume, SLOPE, INTERCEPT)


def assert_same_volume(path, expected, affine, **kwargs):
    values, A = meshpde.read_volume(path, **kwargs)
    assert values.shape == expected.shape and values.dtype == np.float32
    assert np.array_equal(values, expected.astype(np.float32))
    assert np.abs(A - affine).max() < 1e-9
    return values, A


@pytest.mark.parametrize("flip", [(1, 1, 1), (-1, 1, 1), (1, -1, 1), (-1, -1, 1)])
def test_an_oblique_series_with_shuffled_names_equals_its_nifti(tmp_path, volume, expected, flip):
    D = dw.oblique_direction(25.0, flip)
    dw.write_series(tmp_path / "series", volume, SPACING, ORIGIN, D, slope=SLOPE, intercept=INTERCEPT, seed=sum(flip) + 4)
    affine = dw.affine_of(SPACING, ORIGIN, D)
    nifti = dw.write_nifti(tmp_path / "same.nii.gz", expected, affine)
    values, A = assert_same_volume(tmp_path / "series", expected, affine)
    theirs, B = meshpde.read_volume(nifti)
    assert np.array_equal(values, theirs)
    assert np.abs(A - B).max() < 1e-5  # NIfTI's sform is float32


def test_the_slices_are_ordered_by_position_not_by_name_or_instance_number(tmp_path, volume, expected):
    # Names in slice order reversed, and instance numbers against the slice order too.
    D = np.eye(3)
    dw.write_series(tmp_path / "s", volume, SPACING, ORIGIN, D, slope=SLOPE, intercept=INTERCEPT,
                    names=lambda k: f"{1000 - k}.dcm")
    assert_same_volume(tmp_path / "s", expected, dw.affine_of(SPACING, ORIGIN, D))


TRANSFER_SYNTAXES = {
    "--implicit": "1.2.840.10008.1.2",
    "--explicit": "1.2.840.10008.1.2.1",
    "--deflated": "1.2.840.10008.1.2.1.99",
    "--rle": "1.2.840.10008.1.2.5",
    "--jpeg": "1.2.840.10008.1.2.4.70",
    "--jpegls": "1.2.840.10008.1.2.4.80",
    "--j2k": "1.2.840.10008.1.2.4.90",
}


@pytest.fixture(scope="module")
def plain_series(tmp_path_factory, volume):
    folder = tmp_path_factory.mktemp("plain")
    D = dw.oblique_direction(10.0, (1, -1, 1))
    paths = dw.write_series(folder, volume, SPACING, ORIGIN, D, slope=SLOPE, intercept=INTERCEPT)
    return paths, dw.affine_of(SPACING, ORIGIN, D)


@pytest.mark.parametrize("option", sorted(TRANSFER_SYNTAXES))
def test_every_transfer_syntax_reads_the_same_volume(tmp_path, plain_series, expected, option):
    paths, affine = plain_series
    tool = gdcmconv()
    for p in paths:
        subprocess.run([tool, option, str(p), str(tmp_path / p.name)], check=True, capture_output=True)
    written = dw.pydicom.dcmread(tmp_path / paths[0].name, stop_before_pixels=True)
    assert written.file_meta.TransferSyntaxUID == TRANSFER_SYNTAXES[option]
    assert_same_volume(tmp_path, expected, affine)


@pytest.mark.parametrize("option", ["--rle", "--jpeg", "--jpegls", "--j2k"])
def test_a_compressed_multiframe_file_reads_every_frame(tmp_path, volume, expected, option):
    # One fragment a frame (and an offset table): each frame decoded on its own.
    D = dw.oblique_direction(20.0, (1, 1, -1))
    order = np.random.default_rng(9).permutation(volume.shape[2])
    plain = dw.write_enhanced(tmp_path / "enhanced.dcm", volume, SPACING, ORIGIN, D, slope=SLOPE,
                              intercept=INTERCEPT, frame_order=order)
    out = tmp_path / "compressed.dcm"
    subprocess.run([gdcmconv(), option, str(plain), str(out)], check=True, capture_output=True)
    assert dw.pydicom.dcmread(out, stop_before_pixels=True).file_meta.TransferSyntaxUID == TRANSFER_SYNTAXES[option]
    assert_same_volume(out, expected, dw.affine_of(SPACING, ORIGIN, D))


@pytest.mark.parametrize("options, syntax, max_error", [
    (["--jpeg", "--lossy", "-q", "90"], "1.2.840.10008.1.2.4.50", 40),
    (["--j2k", "--lossy", "-q", "40"], "1.2.840.10008.1.2.4.91", 40),
    (["--jpegls", "--lossy", "-e", "2"], "1.2.840.10008.1.2.4.81", 2),  # near-lossless: |error| <= 2 by design
])
def test_lossy_syntaxes_read_within_their_error(tmp_path, volume, options, syntax, max_error):
    # 8-bit grey (what lossy baseline JPEG holds): the values come back within the
    # codec's error, most of them much closer; JPEG-LS near-lossless bounds every error.
    v8 = np.rint((volume - volume.min()) / (volume.max() - volume.min()) * 255)
    D = dw.oblique_direction(10.0)
    paths = dw.write_series(tmp_path / "u8", v8, SPACING, ORIGIN, D, dtype=np.uint8)
    for p in paths:
        subprocess.run([gdcmconv(), *options, str(p), str(tmp_path / p.name)], check=True, capture_output=True)
    assert dw.pydicom.dcmread(tmp_path / paths[0].name, stop_before_pixels=True).file_meta.TransferSyntaxUID == syntax
    values, A = meshpde.read_volume(tmp_path / paths[0].name)
    error = np.abs(values - v8)
    assert error.max() <= max_error and error.mean() < 0.75 * max_error, (error.max(), error.mean())
    assert np.abs(A - dw.affine_of(SPACING, ORIGIN, D)).max() < 1e-9


def test_explicit_big_endian(tmp_path, volume, expected):
    D = dw.oblique_direction(15.0)
    dw.write_series(tmp_path, volume, SPACING, ORIGIN, D, slope=SLOPE, intercept=INTERCEPT,
                    transfer_syntax=dw.ExplicitVRBigEndian)
    written = dw.pydicom.dcmread(next(tmp_path.iterdir()), stop_before_pixels=True)
    assert written.file_meta.TransferSyntaxUID == "1.2.840.10008.1.2.2"
    assert_same_volume(tmp_path, expected, dw.affine_of(SPACING, ORIGIN, D))


def test_an_enhanced_multiframe_file_takes_each_frames_position(tmp_path, volume, expected):
    D = dw.oblique_direction(30.0, (1, -1, 1))
    order = np.random.default_rng(5).permutation(volume.shape[2])  # frames stored out of slice order
    path = dw.write_enhanced(tmp_path / "enhanced.dcm", volume, SPACING, ORIGIN, D, slope=SLOPE,
                             intercept=INTERCEPT, frame_order=order)
    assert_same_volume(path, expected, dw.affine_of(SPACING, ORIGIN, D))
    info = meshpde.info(path)
    assert info["kind"] == "dicom" and info["series"][0]["files"] == [str(path)]


def test_a_real_volume_through_dicom_equals_the_original(tmp_path, data):
    # The aorta angiography (direction diag(-1, -1, 1)) written as a DICOM series.
    values, affine = meshpde.read_volume(data("aorta-mra.mha"))
    spacing = np.linalg.norm(affine[:3, :3], axis=0)
    D = affine[:3, :3] / spacing
    dw.write_series(tmp_path, values, spacing, affine[:3, 3], D, modality="MR", dtype=np.int16)
    ours, A = meshpde.read_volume(tmp_path)
    assert np.array_equal(ours, dw.quantized(values).astype(np.float32))
    assert np.abs(A - affine).max() < 1e-9


def test_elements_of_unknown_vr_are_read_and_a_wrong_vr_is_refused(tmp_path, plain_series, expected, monkeypatch):
    # A tool that did not know an element writes it with VR UN; its value is the same
    # bytes, so the series reads the same. Text where a number belongs is refused.
    paths, affine = plain_series
    monkeypatch.setattr(dw.pydicom.config, "replace_un_with_known_vr", False)  # pydicom would undo UN
    for p in paths:
        ds = dw.pydicom.dcmread(p)
        for keyword in ("ImagePositionPatient", "Rows", "RescaleSlope"):
            e = ds[keyword]
            values = e.value if e.VM > 1 else [e.value]
            raw = struct.pack("<H", e.value) if e.VR == "US" else "\\".join(map(str, values)).encode()
            raw += b" " * (len(raw) % 2)
            ds[keyword] = dw.pydicom.DataElement(e.tag, "UN", raw)
        ds.save_as(tmp_path / p.name, write_like_original=False)
    assert dw.pydicom.dcmread(tmp_path / paths[0].name)["Rows"].VR == "UN"
    assert_same_volume(tmp_path, expected, affine)
    wrong = tmp_path / "wrong"
    wrong.mkdir()
    for p in paths:
        ds = dw.pydicom.dcmread(p)
        ds["RescaleSlope"] = dw.pydicom.DataElement(0x00281053, "UI", "1.2")
        ds.save_as(wrong / p.name, write_like_original=False)
    with pytest.raises(meshpde.InputError, match=r"\(0028,1053\) has value representation UI, not DS"):
        meshpde.read_volume(wrong)


@pytest.mark.parametrize("keyword", ["ImageOrientationPatient", "ImagePositionPatient", "PixelSpacing"])
def test_an_image_without_its_geometry_is_refused_not_placed_at_a_guess(tmp_path, plain_series, keyword):
    paths, _ = plain_series
    for p in paths:
        ds = dw.pydicom.dcmread(p)
        if p == paths[2]:
            del ds[keyword]
        ds.save_as(tmp_path / p.name, write_like_original=False)
    with pytest.raises(meshpde.InputError, match=f"{paths[2].name} has no {keyword}"):
        meshpde.read_volume(tmp_path)


def test_one_file_of_a_series_reads_the_whole_series(plain_series, expected):
    paths, affine = plain_series
    assert_same_volume(paths[3], expected, affine)


@pytest.fixture(scope="module")
def two_series(tmp_path_factory, volume):
    root = tmp_path_factory.mktemp("two")
    a = dw.write_series(root / "study" / "a", volume, SPACING, ORIGIN, np.eye(3), slope=SLOPE, intercept=INTERCEPT,
                        number=3, description="arterial")
    b = dw.write_series(root / "study" / "b", volume[::-1], SPACING, ORIGIN, np.eye(3), slope=SLOPE,
                        intercept=INTERCEPT, number=7, description="venous")
    (root / "study" / "notes.txt").write_text("not an image\n")
    return root, dw.pydicom.dcmread(a[0]).SeriesInstanceUID, dw.pydicom.dcmread(b[0]).SeriesInstanceUID


def test_a_folder_of_two_series_lists_both_and_reads_the_one_chosen(two_series, expected, cli):
    root, uid_a, uid_b = two_series
    with pytest.raises(meshpde.InputError, match=r"holds 2 series[\s\S]*arterial[\s\S]*venous"):
        meshpde.read_volume(root)
    affine = dw.affine_of(SPACING, ORIGIN, np.eye(3))
    assert_same_volume(root, expected, affine, series=3)
    assert_same_volume(root, expected, affine, series=uid_a)
    assert_same_volume(root, expected[::-1], affine, series=uid_b)
    with pytest.raises(meshpde.InputError, match="no series '99'"):
        meshpde.read_volume(root, series=99)
    listing = cli("info", root, "--json", json_out=True)
    assert listing["kind"] == "dicom" and "volume" not in listing
    assert [s["number"] for s in listing["series"]] == [3, 7]
    first = listing["series"][0]
    assert first["uid"] == uid_a and first["description"] == "arterial" and first["modality"] == "CT"
    assert first["size"] == [24, 20, 12] and np.allclose(first["spacing"], SPACING)
    assert np.allclose(first["origin"], ORIGIN) and np.allclose(first["direction"], np.eye(3))
    assert len(first["files"]) == 12 and all(os.path.exists(f) for f in first["files"])
    assert any("notes.txt" in s for s in listing["skipped"])
    chosen = cli("info", root, "--series", "7", "--json", json_out=True)
    assert chosen["volume"]["series"] == uid_b and chosen["volume"]["dims"] == [24, 20, 12]
    assert meshpde.info(root)["series"][1]["uid"] == uid_b


def test_the_direction_is_a_matrix_whose_columns_are_the_voxel_axes(tmp_path, volume, cli):
    D = dw.oblique_direction(40.0, (-1, 1, 1))
    dw.write_series(tmp_path, volume, SPACING, ORIGIN, D, slope=SLOPE, intercept=INTERCEPT)
    listing = cli("info", tmp_path, "--json", json_out=True)
    assert np.allclose(listing["series"][0]["direction"], D, atol=1e-9)
    assert np.allclose(listing["volume"]["direction"], D, atol=1e-9)
    assert np.allclose(meshpde.info(tmp_path)["volume"]["direction"], D, atol=1e-9)


def run_cli(cli_path, *args):
    return subprocess.run([cli_path, *map(str, args)], capture_output=True, text=True, timeout=120)


def test_commands_take_a_dicom_series_as_their_image(tmp_path, data, cli, cli_path):
    # The aorta's level set as a DICOM series: sampling it at the registered mesh's
    # vertices gives the zero level set, as from the original file.
    phi, affine = meshpde.read_volume(data("aorta-levelset.mha"))
    spacing = np.linalg.norm(affine[:3, :3], axis=0)
    dw.write_series(tmp_path / "phi", phi, spacing, affine[:3, 3], affine[:3, :3] / spacing, slope=0.001,
                    modality="MR", dtype=np.int16)
    mesh = data("aorta-closed-6k.vtp")
    ours = cli("sample", mesh, "--image", tmp_path / "phi", "--space", "ras", "--json", json_out=True)
    theirs = cli("sample", mesh, "--image", data("aorta-levelset.mha"), "--space", "ras", "--json", json_out=True)
    assert ours["outside"] == theirs["outside"] == 0
    assert ours["mean_abs"] == pytest.approx(theirs["mean_abs"], abs=2e-3)
    out = tmp_path / "fixed.vtp"
    r = cli("correct", mesh, "--vertex", "1000", "--move", "normal:-1", "--radius", "8", "--image", tmp_path / "phi",
            "--space", "ras", "-o", out, "--json", json_out=True)
    assert r["image"]["pulled_vertices"] > 0 and out.exists()


def test_a_jpeg_stream_cut_short_is_refused_naming_the_file_and_frame(tmp_path, volume, expected):
    # A fragment whose JPEG stream lost its end (and so its end-of-image marker): an
    # error naming the file and the frame, not a silently zero-filled slice.
    from pydicom.encaps import encapsulate, generate_pixel_data_frame
    D = np.eye(3)
    plain = dw.write_enhanced(tmp_path / "enhanced.dcm", volume, SPACING, ORIGIN, D, slope=SLOPE,
                              intercept=INTERCEPT, frame_order=np.arange(volume.shape[2]))
    out = tmp_path / "jpeg.dcm"
    subprocess.run([gdcmconv(), "--jpeg", str(plain), str(out)], check=True, capture_output=True)
    assert_same_volume(out, expected, dw.affine_of(SPACING, ORIGIN, D))  # whole, it reads
    ds = dw.pydicom.dcmread(out)
    frames = list(generate_pixel_data_frame(ds.PixelData, int(ds.NumberOfFrames)))
    assert frames[2].rstrip(b"\0").endswith(b"\xff\xd9")
    frames[2] = frames[2].rstrip(b"\0")[:-40]
    ds.PixelData = encapsulate(frames)
    cut = tmp_path / "cut.dcm"
    ds.save_as(cut)
    with pytest.raises(meshpde.InputError) as e:
        meshpde.read_volume(cut)
    for w in ("cut.dcm", "frame 3", "end-of-image"):
        assert w in str(e.value), f"'{w}' not in {e.value}"


def test_bad_dicom_input_names_the_file_and_exits_1(tmp_path, plain_series, cli_path):
    paths, _ = plain_series
    cases = {}
    empty = tmp_path / "empty"
    empty.mkdir()
    cases["empty"] = (empty, ["empty", "no DICOM images"])
    other = tmp_path / "other"
    other.mkdir()
    (other / "a.txt").write_text("hello\n")
    (other / "b.dcm").write_bytes(b"\0" * 200)
    cases["not dicom"] = (other, ["no DICOM images", "no DICM preamble"])
    truncated = tmp_path / "truncated"
    truncated.mkdir()
    for p in paths:
        shutil.copy(p, truncated / p.name)
    victim = truncated / paths[5].name
    victim.write_bytes(victim.read_bytes()[:700])
    cases["truncated"] = (truncated, [paths[5].name])
    missing = tmp_path / "missing"
    missing.mkdir()
    for k, p in enumerate(paths):
        if k != 6:
            shutil.copy(p, missing / p.name)
    cases["missing slice"] = (missing, ["gap", "missing slice", paths[5].name, paths[7].name])
    for what, (path, words) in cases.items():
        with pytest.raises(meshpde.InputError) as e:
            meshpde.read_volume(path)
        for w in words:
            assert w in str(e.value), f"{what}: '{w}' not in {e.value}"
        r = run_cli(cli_path, "sample", paths[0].parent / "nothing.vtp", "--image", path)
        assert r.returncode == 1
        # info lists what it can read, and says why a series is not one volume; a
        # folder without a DICOM image is an error.
        r = run_cli(cli_path, "info", path)
        if what in ("missing slice", "truncated"):
            assert r.returncode == 0 and "not readable as one volume" in r.stdout
            assert words[-1] in r.stdout
        else:
            assert r.returncode == 1 and "meshpde: error:" in r.stderr and words[0] in r.stderr


def test_a_tilted_or_mixed_series_is_refused_with_the_slices_named(tmp_path, volume):
    D = np.eye(3)
    tilted = dw.write_series(tmp_path / "tilt", volume, SPACING, ORIGIN, D)
    # Gantry tilt: each slice shifted along y in proportion to its position.
    for k, p in enumerate(tilted):
        ds = dw.pydicom.dcmread(p)
        pos = [float(x) for x in ds.ImagePositionPatient]
        ds.ImagePositionPatient = [dw.ds_text(pos[0]), dw.ds_text(pos[1] + 0.3 * k), dw.ds_text(pos[2])]
        ds.save_as(p)
    with pytest.raises(meshpde.InputError, match="not stacked along their normal.*gantry tilt"):
        meshpde.read_volume(tmp_path / "tilt")
    mixed = dw.write_series(tmp_path / "mixed", volume, SPACING, ORIGIN, D)
    small = dw.write_series(tmp_path / "small", volume[:10, :10], SPACING, ORIGIN, D)
    ds = dw.pydicom.dcmread(small[4])
    ds.SeriesInstanceUID = dw.pydicom.dcmread(mixed[0]).SeriesInstanceUID
    ds.save_as(tmp_path / "mixed" / "odd.dcm")
    with pytest.raises(meshpde.InputError, match="mixed image sizes.*odd.dcm"):
        meshpde.read_volume(tmp_path / "mixed")
    dup = dw.write_series(tmp_path / "dup", volume, SPACING, ORIGIN, D)
    shutil.copy(dup[2], tmp_path / "dup" / "copy.dcm")
    with pytest.raises(meshpde.InputError, match="same position"):
        meshpde.read_volume(tmp_path / "dup")
