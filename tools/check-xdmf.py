#!/usr/bin/python3
"""Check a run's XDMF index with the real readers: ParaView's three XDMF readers and meshio.

    tools/check-xdmf.py RUN.xdmf [--png OUT.png] [--tol 1e-12]

Every reader must show the mesh (points = rows of /mesh/coordinates, or of a finite-strain
run's /fields/position where it was written, which must be coordinates + displacement;
cells = /mesh/cells kind by kind in file order) and every field of /fields at the first and the last time (of the run
and of each field's own axis) with the values of the HDF5 file, within `tol` relative to the
field's largest value; meshio (meshio.xdmf.TimeSeriesReader) must read every step. Prints one
line per check and a summary; exits 1 if any check fails. With --png, renders the last time
as ParaView opens the file (OpenDataFile), coloured by displacement magnitude.

How each reader gives the components (measured, and checked here):
- XDMFReader (legacy): 2-component vectors padded to 3 (z = 0); Tensor6 expanded to the full
  9-component tensor row by row, reading the 6 stored as xx xy xz yy yz zz (XDMF's order).
- Xdmf3ReaderS, Xdmf3ReaderT: components as stored (2-component vectors stay 2; Tensor6 stays
  6, which ParaView labels with VTK's order XX YY ZZ XY YZ XZ).
- meshio: as stored.

Runs in two processes: this one (Debian's python3 with python3-h5py and python3-meshio) reads
the HDF5 file and meshio, and runs ParaView's `pvbatch --force-offscreen-rendering` on this
script (--dump) to record what each ParaView reader shows (ParaView's HDF5 and h5py's are two
builds of the library, kept out of one process). Rendering needs an X server (Debian's
ParaView has no EGL/OSMesa): without a display run it under `xvfb-run -a`.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

READERS = ["XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT"]
# /mesh/cells/<kind> in the writer's order (gmsh type order) and the VTK cell types.
KINDS = ["line", "triangle", "quadrilateral", "tetrahedron", "hexahedron", "point"]
VTK_TYPE = {"line": 3, "triangle": 5, "quadrilateral": 9, "tetrahedron": 10, "hexahedron": 12,
            "point": 1}
MESHIO_TYPE = {"line": "line", "triangle": "triangle", "quadrilateral": "quad",
               "tetrahedron": "tetra", "hexahedron": "hexahedron", "point": "vertex"}


# ---------------------------------------------------------------- ParaView side (pvbatch)

def dump(xdmf, times, out, png):
    """Record what each ParaView reader shows at `times` into the .npz `out`."""
    import paraview.simple as S
    from paraview import servermanager as sm
    from vtk.util.numpy_support import vtk_to_numpy

    rec = {}
    for name in READERS:
        if name == "XDMFReader":
            r = S.XDMFReader(FileNames=[xdmf])
            r.PointArrayStatus = r.GetProperty("PointArrayInfo")[::2]
            r.CellArrayStatus = r.GetProperty("CellArrayInfo")[::2]
        else:
            r = getattr(S, name)(FileName=[xdmf])
        rec[f"{name}/times"] = np.array(r.TimestepValues or [], float)
        for i, t in enumerate(times):
            r.UpdatePipeline(t)
            data = sm.Fetch(r)
            leaves = [data]
            if data.IsA("vtkCompositeDataSet"):  # e.g. one block per grid of a collection
                leaves, it = [], data.NewIterator()
                it.InitTraversal()
                while not it.IsDoneWithTraversal():
                    leaves.append(it.GetCurrentDataObject())
                    it.GoToNextItem()
            rec[f"{name}/{i}/blocks"] = np.array(len(leaves))
            for b, g in enumerate(leaves):
                key = f"{name}/{i}/{b}"
                rec[f"{key}/points"] = vtk_to_numpy(g.GetPoints().GetData()).astype(float)
                rec[f"{key}/types"] = vtk_to_numpy(g.GetCellTypesArray()).astype(int)
                rec[f"{key}/conn"] = vtk_to_numpy(g.GetCells().GetConnectivityArray()).astype(int)
                for where, fd in (("point", g.GetPointData()), ("cell", g.GetCellData())):
                    for j in range(fd.GetNumberOfArrays()):
                        a = fd.GetArray(j)
                        v = vtk_to_numpy(a).astype(float).reshape(a.GetNumberOfTuples(), -1)
                        rec[f"{key}/{where}/{a.GetName()}"] = v
        # ParaView's labels of the components (what the GUI shows), at the last time.
        cd = r.GetDataInformation().DataInformation
        for where, info in (("point", cd.GetPointDataInformation()),
                            ("cell", cd.GetCellDataInformation())):
            for j in range(info.GetNumberOfArrays()):
                ai = info.GetArrayInformation(j)
                labels = [ai.GetComponentName(c) or "" for c in range(ai.GetNumberOfComponents())]
                rec[f"{name}/gui/{where}/{ai.GetName()}"] = np.array(labels, str)
        S.Delete(r)
    np.savez(out, **rec)

    if png:
        r = S.OpenDataFile(xdmf)
        print(f"OpenDataFile picks {r.GetXMLName()}")
        view = S.GetActiveViewOrCreate("RenderView")
        view.ViewSize = [800, 600]
        view.ViewTime = times[-1]
        view.OrientationAxesVisibility = 0
        shown = S.Show(r, view)
        pts = r.PointData.keys()
        field = "displacement" if "displacement" in pts else (pts[0] if pts else None)
        if field:
            S.ColorBy(shown, ("POINTS", field, "Magnitude"))
            shown.RescaleTransferFunctionToDataRange(True, False)
        bounds = r.GetDataInformation().GetBounds()
        if bounds[5] - bounds[4] > 1e-12 * max(1.0, bounds[1] - bounds[0]):
            view.CameraPosition = [1, -1.5, 1]
            view.CameraViewUp = [0, 0, 1]
        view.ResetCamera()
        S.SaveScreenshot(png, view, ImageResolution=[800, 600])


# ---------------------------------------------------------------- the reference (h5py)

class Run:
    """The HDF5 file behind an XDMF index, as the checks need it."""

    def __init__(self, xdmf):
        import h5py

        root = ET.parse(xdmf).getroot()
        item = next(d for d in root.iter("DataItem") if d.get("Format") == "HDF")
        h5 = os.path.join(os.path.dirname(xdmf), item.text.strip().split(":")[0])
        # Where each attribute lives (Node or Cell), from the index itself.
        self.center = {a.get("Name"): a.get("Center") for a in root.iter("Attribute")}
        f = h5py.File(h5, "r")
        self.coords = f["mesh/coordinates"][()]
        self.kinds = [k for k in KINDS if k in f["mesh/cells"]]
        self.cells = [(k, f[f"mesh/cells/{k}"][()].astype(int)) for k in self.kinds]
        self.cell_rank = f["mesh/cell_rank"][()].astype(float)
        self.time = f["time"][()]
        self.fields = {}
        for name in sorted(f["fields"]):
            if name.endswith("_time") or name.endswith("_step"):
                continue
            axis = f[f"fields/{name}_time"][()] if f"fields/{name}_time" in f else self.time
            self.fields[name] = (f[f"fields/{name}"][()], axis)
        f.close()

    def points(self, t):
        """The points the index should show at time t: the positions written then (a
        finite-strain run's /fields/position), else /mesh/coordinates."""
        r = self.row("position", t) if "position" in self.fields else None
        return self.coords if r is None else self.fields["position"][0][r]

    def row(self, name, t):
        """Row of field `name` written at time t (None if not written then)."""
        _, axis = self.fields[name]
        hit = np.nonzero(np.abs(axis - t) <= 1e-12 * max(abs(t), 1e-300))[0]
        return int(hit[0]) if len(hit) else None


class Checks:
    def __init__(self):
        self.passed, self.failed = 0, []

    def __call__(self, ok, what):
        if ok:
            self.passed += 1
        else:
            self.failed.append(what)
        print(("ok   " if ok else "FAIL ") + what)


def rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return np.inf
    scale = max(np.abs(a).max(initial=0.0), np.abs(b).max(initial=0.0), 1e-300)
    return np.abs(a - b).max(initial=0.0) / scale


def full_tensor(s):
    """6 components xx xy xz yy yz zz -> 9, row by row."""
    xx, xy, xz, yy, yz, zz = s.T
    return np.stack([xx, xy, xz, xy, yy, yz, xz, yz, zz], axis=1)


def compare_array(got, want, tol):
    """(ok, how): the reader's array against the stored one, in the forms readers give."""
    c = want.shape[1]
    if got.shape == want.shape:
        return rel(got, want) <= tol, "as stored"
    if c == 2 and got.shape == (want.shape[0], 3):
        return rel(got[:, :2], want) <= tol and not got[:, 2].any(), "padded to 3 (z = 0)"
    if c == 6 and got.shape == (want.shape[0], 9):
        return rel(got, full_tensor(want)) <= tol, "9: full tensor of xx xy xz yy yz zz"
    return False, f"shape {got.shape} against {want.shape}"


def check_paraview(run, xdmf, checks, tol, png):
    # The times to look at: the run's first and last, and each field's own first and last.
    times = sorted({run.time[0], run.time[-1]}
                   | {t for _, axis in run.fields.values() for t in (axis[0], axis[-1])
                      if len(axis)})
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "dump.npz")
        cmd = ["pvbatch", "--force-offscreen-rendering", os.path.abspath(__file__), "--dump",
               out, "--times", ",".join(repr(float(t)) for t in times)]
        if png:
            cmd += ["--png", os.path.abspath(png)]
        cmd.append(os.path.abspath(xdmf))
        p = subprocess.run(cmd, capture_output=True, text=True)
        noise = [l for l in p.stderr.splitlines() if "Skipping" in l or "ERR" in l]
        for line in sorted(set(noise)):
            print(f"pvbatch: {line.strip()}")
        print(p.stdout, end="")
        checks(p.returncode == 0 and os.path.exists(out),
               f"pvbatch ran (exit {p.returncode}){'' if p.returncode == 0 else ': ' + p.stderr[-2000:]}")
        if not os.path.exists(out):
            return
        rec = dict(np.load(out))

    want_types = np.concatenate([np.full(len(c), VTK_TYPE[k]) for k, c in run.cells])
    want_conn = np.concatenate([c.ravel() for _, c in run.cells])
    for name in READERS:
        got_times = rec[f"{name}/times"]
        checks(rel(got_times, run.time) <= tol, f"{name}: {len(got_times)} times = /time")
        for i, t in enumerate(times):
            at = f"{name} t={t:.6g}"
            # A grid per step, or (a spatial collection) a grid per cell kind, each with all
            # the points: cells and cell fields are taken block after block.
            blocks = [f"{name}/{i}/{b}" for b in range(int(rec[f"{name}/{i}/blocks"]))]
            checks(len(blocks) > 0, f"{at}: {len(blocks)} grid(s)")
            if not blocks:
                continue
            where = "position" if run.points(t) is not run.coords else "/mesh/coordinates"
            ok = all(rel(rec[f"{b}/points"], run.points(t)) <= tol for b in blocks)
            checks(ok, f"{at}: points = {where}")
            ok = (np.array_equal(np.concatenate([rec[f"{b}/types"] for b in blocks]), want_types)
                  and np.array_equal(np.concatenate([rec[f"{b}/conn"] for b in blocks]), want_conn))
            checks(ok, f"{at}: cells = /mesh/cells ({', '.join(run.kinds)})")

            def shown(where, field):
                parts = [rec.get(f"{b}/{where}/{field}") for b in blocks]
                if any(p is None for p in parts):
                    return None
                if where == "cell":
                    return np.concatenate(parts)
                same = all(p.shape == parts[0].shape and (p == parts[0]).all() for p in parts)
                return parts[0] if same else np.full((0, 0), np.nan)

            for field, (values, _) in run.fields.items():
                r = run.row(field, t)
                if r is None:
                    continue
                where = "cell" if run.center.get(field) == "Cell" else "point"
                got = shown(where, field)
                if got is None:
                    checks(False, f"{at}: {field} missing")
                    continue
                ok, how = compare_array(got, values[r], tol)
                labels = rec.get(f"{name}/gui/{where}/{field}")
                lab = f"; ParaView labels {' '.join(labels)}" if values.shape[2] == 6 and labels is not None else ""
                checks(ok, f"{at}: {where} field {field} = row {r} ({how}{lab})")
            got = shown("cell", "partition")
            checks(got is not None and rel(got[:, 0], run.cell_rank) <= tol,
                   f"{at}: partition = /mesh/cell_rank")


def check_position(run, checks, tol):
    """A finite-strain run's positions are X + u, at every row the displacement has."""
    if "position" not in run.fields:
        return
    pos, axis = run.fields["position"]
    disp, daxis = run.fields.get("displacement", (None, None))
    checks(disp is not None and rel(axis, daxis) <= tol,
           f"position: written with the displacement ({len(axis)} rows)")
    if disp is None:
        return
    for r in range(min(len(pos), len(disp))):
        x = run.coords.copy()
        x[:, : disp.shape[2]] += disp[r]
        checks(rel(pos[r], x) <= tol, f"position row {r} = /mesh/coordinates + displacement")


def check_meshio(run, xdmf, checks, tol):
    import meshio

    try:
        with meshio.xdmf.TimeSeriesReader(xdmf) as r:
            points, cells = r.read_points_cells()
            # meshio reads the first grid's geometry only.
            checks(rel(points, run.points(run.time[0])) <= tol, "meshio: points = the first grid's")
            ok = [(c.type, c.data.tolist()) for c in cells] == \
                [(MESHIO_TYPE[k], c.tolist()) for k, c in run.cells]
            checks(ok, "meshio: cells = /mesh/cells")
            checks(r.num_steps == len(run.time), f"meshio: {r.num_steps} steps")
            for k in range(r.num_steps):
                t, point_data, cell_data = r.read_data(k)
                checks(rel(t, run.time[k]) <= tol, f"meshio step {k}: t = /time[{k}]")
                for field, (values, _) in run.fields.items():
                    row = run.row(field, run.time[k])
                    if row is None:
                        continue
                    if field in cell_data:
                        got = np.concatenate(cell_data[field]).reshape(values.shape[1], -1)
                    elif field in point_data:
                        got = point_data[field].reshape(values.shape[1], -1)
                    else:
                        checks(False, f"meshio step {k}: {field} missing")
                        continue
                    checks(rel(got, values[row]) <= tol, f"meshio step {k}: {field} = row {row}")
    except Exception as e:  # a reader that cannot read the file is a failed check
        checks(False, f"meshio: {type(e).__name__}: {e}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("xdmf")
    ap.add_argument("--png")
    ap.add_argument("--tol", type=float, default=1e-12)
    ap.add_argument("--dump", help=argparse.SUPPRESS)
    ap.add_argument("--times", help=argparse.SUPPRESS)
    a = ap.parse_args()
    xdmf = os.path.abspath(a.xdmf)  # Xdmf3 misplaces the .h5 of a bare file name
    if a.dump:
        dump(xdmf, [float(t) for t in a.times.split(",")], a.dump, a.png)
        return 0
    run = Run(xdmf)
    checks = Checks()
    check_position(run, checks, a.tol)
    check_paraview(run, xdmf, checks, a.tol, a.png)
    check_meshio(run, xdmf, checks, a.tol)
    print(f"check-xdmf: {checks.passed} checks passed, {len(checks.failed)} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    # No sys.exit(0) under pvbatch: exiting through SystemExit after rendering makes its
    # teardown fail (X error GLXBadContext, exit code 1).
    rc = main()
    if rc:
        sys.exit(rc)
