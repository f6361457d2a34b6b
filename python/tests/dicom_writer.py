"""DICOM series written by the tests themselves, with Debian's python3-pydicom.

A volume ``values[i, j, k]`` (i along a row, j down a column, k the slice) with the
geometry of meshpde.read_volume (LPS mm: ``affine = [direction * spacing | origin]``)
becomes one file per slice, or one enhanced multi-frame file; the stored pixels are
``(values - intercept) / slope`` so that the reader's rescale gives the values back.
"""
from __future__ import annotations

import datetime
import gzip
import pathlib
import struct

import numpy as np
import pydicom
from pydicom.dataset import Dataset, FileDataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import ExplicitVRBigEndian, ExplicitVRLittleEndian, ImplicitVRLittleEndian, generate_uid

CT_IMAGE = "1.2.840.10008.5.1.4.1.1.2"
ENHANCED_CT_IMAGE = "1.2.840.10008.5.1.4.1.1.2.1"


def affine_of(spacing, origin, direction):
    A = np.eye(4)
    A[:3, :3] = np.asarray(direction, float) @ np.diag(spacing)
    A[:3, 3] = origin
    return A


def ds_text(x):
    """A DS value of at most 16 characters that reads back as x to about 1e-10 relative."""
    for digits in range(15, 5, -1):
        s = f"{x:.{digits}g}"
        if len(s) <= 16:
            return s
    return f"{x:.6g}"


def quantized(values, slope=1.0, intercept=0.0, dtype=np.int16):
    """The values a reader gives back: the stored integers times slope plus intercept."""
    return _stored(values, slope, intercept, dtype).astype(np.float64) * slope + intercept


def _stored(values, slope, intercept, dtype):
    stored = np.rint((np.asarray(values, float) - intercept) / slope)
    info = np.iinfo(dtype)
    assert stored.min() >= info.min and stored.max() <= info.max, "values out of the stored type's range"
    return stored.astype(dtype)


def _base(uid_series, uid_study, number, description, modality, sop_class, transfer_syntax):
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = transfer_syntax
    meta.ImplementationClassUID = generate_uid()
    ds = FileDataset(None, {}, file_meta=meta, preamble=b"\0" * 128)
    ds.is_little_endian = transfer_syntax != ExplicitVRBigEndian
    ds.is_implicit_VR = transfer_syntax == ImplicitVRLittleEndian
    ds.SOPClassUID = sop_class
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.StudyInstanceUID = uid_study
    ds.SeriesInstanceUID = uid_series
    ds.SeriesNumber = number
    ds.SeriesDescription = description
    ds.Modality = modality
    ds.PatientName = "Test^Phantom"
    ds.PatientID = "meshpde-test"
    ds.StudyDate = datetime.date(2026, 1, 1).strftime("%Y%m%d")
    ds.FrameOfReferenceUID = generate_uid()
    return ds


def _pixels(ds, stored):
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    ds.BitsAllocated = stored.dtype.itemsize * 8
    ds.BitsStored = stored.dtype.itemsize * 8
    ds.HighBit = ds.BitsStored - 1
    ds.PixelRepresentation = 1 if np.issubdtype(stored.dtype, np.signedinteger) else 0
    order = ">" if not ds.is_little_endian else "<"
    ds.PixelData = stored.astype(stored.dtype.newbyteorder(order)).tobytes()


def write_series(folder, values, spacing, origin, direction, *, slope=1.0, intercept=0.0, dtype=np.int16,
                 number=1, description="meshpde test", modality="CT", uid=None, names=None,
                 transfer_syntax=ExplicitVRLittleEndian, seed=0):
    """One file per slice in `folder`; returns the file paths in slice order. `names`
    (a function of k) or, by default, shuffled names that sort in no useful order."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    values = np.asarray(values)
    ni, nj, nk = values.shape
    direction = np.asarray(direction, float)
    uid = uid or generate_uid()
    study = generate_uid()
    rng = np.random.default_rng(seed)
    shuffled = rng.permutation(nk)
    stored = _stored(values, slope, intercept, dtype)
    paths = []
    for k in range(nk):
        ds = _base(uid, study, number, description, modality, CT_IMAGE, transfer_syntax)
        pos = np.asarray(origin, float) + direction[:, 2] * spacing[2] * k
        ds.ImagePositionPatient = [ds_text(x) for x in pos]
        ds.ImageOrientationPatient = [ds_text(x) for x in np.concatenate([direction[:, 0], direction[:, 1]])]
        ds.PixelSpacing = [ds_text(spacing[1]), ds_text(spacing[0])]
        ds.SliceThickness = ds_text(spacing[2])
        ds.Rows, ds.Columns = nj, ni
        # The instance numbers run against the slice order, so neither they nor the names order the slices.
        ds.InstanceNumber = int(nk - k)
        ds.RescaleSlope = ds_text(slope)
        ds.RescaleIntercept = ds_text(intercept)
        _pixels(ds, np.ascontiguousarray(stored[:, :, k].T))
        name = names(k) if names else f"IM{shuffled[k]:04d}.dcm"
        path = folder / name
        ds.save_as(path, write_like_original=False)
        paths.append(path)
    return paths


def write_enhanced(path, values, spacing, origin, direction, *, slope=1.0, intercept=0.0, dtype=np.int16,
                   number=1, description="enhanced", frame_order=None):
    """One enhanced CT file: every frame's position in its functional group, the
    orientation, spacing and rescale in the shared groups. `frame_order` stores the
    slices in another order (their positions still say where each lies)."""
    values = np.asarray(values)
    ni, nj, nk = values.shape
    direction = np.asarray(direction, float)
    order = list(frame_order) if frame_order is not None else list(range(nk))
    ds = _base(generate_uid(), generate_uid(), number, description, "CT", ENHANCED_CT_IMAGE, ExplicitVRLittleEndian)
    ds.NumberOfFrames = nk
    ds.Rows, ds.Columns = nj, ni
    shared = Dataset()
    orient = Dataset()
    orient.ImageOrientationPatient = [ds_text(x) for x in np.concatenate([direction[:, 0], direction[:, 1]])]
    measures = Dataset()
    measures.PixelSpacing = [ds_text(spacing[1]), ds_text(spacing[0])]
    measures.SliceThickness = ds_text(spacing[2])
    transform = Dataset()
    transform.RescaleSlope = ds_text(slope)
    transform.RescaleIntercept = ds_text(intercept)
    transform.RescaleType = "HU"
    shared.PlaneOrientationSequence = Sequence([orient])
    shared.PixelMeasuresSequence = Sequence([measures])
    shared.PixelValueTransformationSequence = Sequence([transform])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    per = []
    for k in order:
        item = Dataset()
        pos = Dataset()
        pos.ImagePositionPatient = [ds_text(x) for x in np.asarray(origin, float) + direction[:, 2] * spacing[2] * k]
        item.PlanePositionSequence = Sequence([pos])
        per.append(item)
    ds.PerFrameFunctionalGroupsSequence = Sequence(per)
    stored = _stored(values, slope, intercept, dtype)
    frames = np.stack([stored[:, :, k].T for k in order])  # frames x rows x columns
    _pixels(ds, np.ascontiguousarray(frames))
    ds.save_as(path, write_like_original=False)
    return pathlib.Path(path)


def write_nifti(path, values, affine_lps):
    """A NIfTI-1 file of the same volume, by hand (float32, sform in RAS), for the
    voxel-for-voxel comparison."""
    values = np.asarray(values, np.float32)
    ras = np.diag([-1.0, -1.0, 1.0, 1.0]) @ affine_lps
    hdr = bytearray(348)
    struct.pack_into("<i", hdr, 0, 348)
    dims = [3, *values.shape, 1, 1, 1, 1]
    struct.pack_into("<8h", hdr, 40, *dims)
    struct.pack_into("<hh", hdr, 70, 16, 32)  # float32
    pixdim = [1.0, *np.linalg.norm(affine_lps[:3, :3], axis=0), 1, 1, 1, 1]
    struct.pack_into("<8f", hdr, 76, *pixdim)
    struct.pack_into("<f", hdr, 108, 352.0)  # vox_offset
    struct.pack_into("<f", hdr, 112, 1.0)  # scl_slope
    struct.pack_into("<hh", hdr, 252, 0, 2)  # qform_code 0, sform_code 2 (aligned)
    for r, off in enumerate((280, 296, 312)):
        struct.pack_into("<4f", hdr, off, *ras[r])
    hdr[344:348] = b"n+1\0"
    data = bytes(hdr) + b"\0" * 4 + values.tobytes(order="F")
    path = pathlib.Path(path)
    if path.name.endswith(".gz"):
        data = gzip.compress(data)
    path.write_bytes(data)
    return path


def oblique_direction(angle_deg=20.0, flip=(1, 1, 1)):
    """An orthonormal, right-handed LPS direction matrix turned about an oblique axis, its
    first two columns' signs as `flip` says (the third is their cross product)."""
    a = np.radians(angle_deg)
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
    R[:, 0] *= flip[0]
    R[:, 1] *= flip[1]
    R[:, 2] = np.cross(R[:, 0], R[:, 1])
    return R


def ct_volume(shape=(24, 20, 12), seed=1):
    """A smooth CT-like volume in HU with a bright ball, for comparisons."""
    rng = np.random.default_rng(seed)
    i, j, k = np.meshgrid(*[np.arange(n) for n in shape], indexing="ij")
    c = np.array(shape) / 2
    r = np.sqrt((i - c[0]) ** 2 + (j - c[1]) ** 2 + ((k - c[2]) * 1.5) ** 2)
    v = np.where(r < min(shape) / 3, 400.0, -900.0) + 30 * (i - j) + rng.integers(-20, 20, shape)
    return v.astype(np.float64)


__all__ = ["affine_of", "quantized", "write_series", "write_enhanced", "write_nifti", "oblique_direction", "ct_volume",
           "ExplicitVRBigEndian", "ExplicitVRLittleEndian", "ImplicitVRLittleEndian", "pydicom"]
