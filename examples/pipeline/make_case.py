#!/usr/bin/python3
"""A synthetic case for docs/pipeline.md, made by meshpde itself.

    /usr/bin/python3 examples/pipeline/make_case.py [FOLDER]     (default: case)

writes FOLDER/ct/ (a CT angiography as a DICOM series: one file a slice, 0.7 x 0.7 x 1 mm,
stored values + RescaleIntercept -1024 = Hounsfield units) of a Y bifurcation filled with
contrast beside a spine, and FOLDER/vessels.seg.nrrd (a 3D Slicer segmentation of two
segments, "artery" and "spine") whose artery has a dent of 1.5 mm that the scan does not
have: the error to correct. Needs meshpde's Python module, numpy, scipy and pydicom
(Debian: python3-numpy python3-scipy python3-pydicom).
"""
import datetime
import pathlib
import sys
import tempfile

import numpy as np
import pydicom
from pydicom.dataset import FileDataset, FileMetaDataset
from pydicom.uid import CTImageStorage, ExplicitVRLittleEndian, generate_uid
from scipy import ndimage

import meshpde

SPACING = np.array([0.7, 0.7, 1.0])  # mm: columns, rows, slices
MARGIN = 15.0  # mm of tissue around the vessels
HU = {"tissue": 40, "blood": 300, "bone": 700}


def write_ct_series(folder, hu, affine):
    """One DICOM file a slice of `hu[i, j, k]` (axial, LPS), stored as HU + 1024."""
    folder.mkdir(parents=True, exist_ok=True)
    study, series, frame = generate_uid(), generate_uid(), generate_uid()
    stored = np.clip(np.rint(hu + 1024), 0, 4095).astype(np.uint16)
    for k in range(hu.shape[2]):
        meta = FileMetaDataset()
        meta.MediaStorageSOPClassUID = CTImageStorage
        meta.MediaStorageSOPInstanceUID = generate_uid()
        meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds = FileDataset(None, {}, file_meta=meta, preamble=b"\0" * 128)
        ds.is_little_endian, ds.is_implicit_VR = True, False
        ds.SOPClassUID, ds.SOPInstanceUID = CTImageStorage, meta.MediaStorageSOPInstanceUID
        ds.StudyInstanceUID, ds.SeriesInstanceUID, ds.FrameOfReferenceUID = study, series, frame
        ds.Modality, ds.SeriesNumber, ds.SeriesDescription = "CT", 3, "synthetic CTA (meshpde)"
        ds.PatientName, ds.PatientID = "Synthetic^Bifurcation", "meshpde-example"
        ds.StudyDate = datetime.date(2026, 1, 1).strftime("%Y%m%d")
        ds.InstanceNumber = k + 1
        ds.ImagePositionPatient = [f"{x:.4f}" for x in affine[:3, 3] + k * affine[:3, 2]]
        ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
        ds.PixelSpacing = [f"{SPACING[1]:g}", f"{SPACING[0]:g}"]  # between rows, between columns
        ds.SliceThickness = f"{SPACING[2]:g}"
        ds.Rows, ds.Columns = hu.shape[1], hu.shape[0]
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 12, 11, 0
        ds.RescaleIntercept, ds.RescaleSlope, ds.RescaleType = "-1024", "1", "HU"
        ds.PixelData = np.ascontiguousarray(stored[:, :, k].T).tobytes()  # rows along j
        ds.save_as(folder / f"IM{k + 1:05d}.dcm", write_like_original=False)


def main(out):
    out.mkdir(parents=True, exist_ok=True)
    true_V, true_F = meshpde.generate.bifurcation()  # the vessel as scanned
    seg_V, seg_F = meshpde.generate.bifurcation(dent=True)  # as segmented: dented at (2.5, 0, -10)
    lo = true_V.min(axis=0) - MARGIN
    dims = np.ceil((true_V.max(axis=0) + MARGIN - lo) / SPACING).astype(int)
    affine = np.eye(4)
    affine[:3, :3] = np.diag(SPACING)
    affine[:3, 3] = lo
    with tempfile.TemporaryDirectory() as tmp:
        grid = pathlib.Path(tmp) / "grid.nrrd"  # the grid both surfaces are voxelized on
        meshpde.write_segmentation(grid, np.zeros(dims, np.int32), affine)
        lumen = meshpde.voxelize(true_V, true_F, grid, oversampling=3)[0] > 0
        dented = meshpde.voxelize(seg_V, seg_F, grid)[0] > 0
    # A spine behind the vessels (+y is posterior in LPS).
    x, y, _ = np.meshgrid(*(lo[a] + SPACING[a] * np.arange(dims[a]) for a in range(3)), indexing="ij")
    spine = x**2 + (y - 13.0) ** 2 < 4.5**2
    hu = np.full(dims, float(HU["tissue"]))
    hu[lumen] = HU["blood"]
    hu[spine] = HU["bone"]
    hu = ndimage.gaussian_filter(hu, 0.8 / SPACING)  # the scanner's blur, 0.8 mm
    hu += np.random.default_rng(3).normal(0.0, 12.0, dims)  # and its noise
    write_ct_series(out / "ct", hu, affine)
    labels = np.zeros(dims, np.int32)
    labels[dented] = 1
    labels[spine] = 2
    segments = [{"name": "artery", "id": "artery", "label": 1, "color": (0.85, 0.25, 0.2)},
                {"name": "spine", "id": "spine", "label": 2, "color": (0.95, 0.9, 0.75)}]
    meshpde.write_segmentation(out / "vessels.seg.nrrd", labels, affine, segments)
    print(f"wrote {out / 'ct'} ({dims[2]} slices of {dims[0]} x {dims[1]}) and {out / 'vessels.seg.nrrd'}")


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "case"))
