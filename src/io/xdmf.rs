//! XDMF 3 index of a run's HDF5 file, for ParaView and meshio: a temporal collection with one
//! uniform grid per written step (mesh, every field written then, partition). Written by rank 0
//! beside the `.h5` at the end of a run (finished, failed or interrupted).
//!
//! **Why the index has views in the HDF5 file.** A field is one dataset of all its written
//! steps, `/fields/<name>` [rows, entries, components], and a grid needs one row of it. XDMF's
//! way to say "one row" is a `HyperSlab` (or `Function`) DataItem, and no one form of it is
//! read by every reader (measured with ParaView 5.11 and meshio 7.0, tests/paraview.rs):
//! - `ItemType="HyperSlab"`: the legacy `XDMFReader` reads it; the Xdmf3 readers
//!   (`Xdmf3ReaderS`/`T`, the ones ParaView picks for `.xdmf`) drop the attribute with
//!   "Skipping unrecognized array type [None]" whatever attributes the item carries: Xdmf3
//!   turns it into a reference array whose number type is unknown until it is read, and VTK's
//!   Xdmf3 bridge checks that type before it reads. `ItemType="Function"` fails alike.
//! - Xdmf3's own hyperslab syntax in the HDF path (`file.h5:/ds|start:stride:count:dims`):
//!   the Xdmf3 readers read it, `XDMFReader` cannot open the dataset.
//! - meshio reads neither (a HyperSlab item has no `Format`; it reads whole datasets).
//!
//! So every field row the index shows is a plain dataset: `/xdmf/<name>/<row>` [entries,
//! components], an HDF5 *virtual dataset* mapping row `row` of `/fields/<name>` (no data is
//! copied; source file "." = this file, so the pair of files can be moved). Every reader reads
//! those. Meshes with several cell kinds get one `Mixed` topology, `/xdmf/topology` (per cell
//! its XDMF type code, for polylines and polyvertices the node count, then its nodes; cells in
//! the order of `/mesh/cells`, kinds in file order), so a step is one grid whatever the mesh:
//! cell fields and the partition need no slicing per kind, and meshio's time-series reader
//! (one uniform grid per step) reads mixed meshes too.
//!
//! A finite-strain run writes the nodes' current positions (`/fields/position`) with the
//! displacement; a step's grid then has its geometry from that row's view, so ParaView draws
//! the bodies where they are. Other steps, and small-strain runs, use `/mesh/coordinates`.

use std::fmt::Write as _;
use std::path::Path;

use super::layout;
use crate::error::{Error, Result};
use crate::mesh::ElementKind;
use crate::rows::{FieldSpec, Location};

/// What the XDMF file describes.
pub struct XdmfLayout<'a> {
    /// HDF5 file name as referenced from the XDMF (same folder).
    pub h5_name: &'a str,
    pub n_nodes: usize,
    pub dim: usize,
    /// Cell kinds with their counts, in the order of /mesh/cells.
    pub cells: &'a [(ElementKind, usize)],
    /// Each written step: time, and the row of each field (plan order) written then.
    pub steps: &'a [(f64, Vec<Option<usize>>)],
    /// The fields with the number of rows each has in the file.
    pub fields: &'a [(FieldSpec, usize)],
}

impl XdmfLayout<'_> {
    fn n_cells(&self) -> usize {
        self.cells.iter().map(|c| c.1).sum()
    }
    fn mixed(&self) -> bool {
        self.cells.len() > 1
    }
}

fn topology_name(kind: ElementKind) -> &'static str {
    match kind {
        ElementKind::Tri3 => "Triangle",
        ElementKind::Quad4 => "Quadrilateral",
        ElementKind::Tet4 => "Tetrahedron",
        ElementKind::Hex8 => "Hexahedron",
        ElementKind::Line2 => "Polyline",
        ElementKind::Point1 => "Polyvertex",
    }
}

/// XDMF's code of a cell kind in a `Mixed` topology, and whether the node count follows it
/// (polylines and polyvertices).
fn mixed_code(kind: ElementKind) -> (u64, bool) {
    match kind {
        ElementKind::Point1 => (1, true),
        ElementKind::Line2 => (2, true),
        ElementKind::Tri3 => (4, false),
        ElementKind::Quad4 => (5, false),
        ElementKind::Tet4 => (6, false),
        ElementKind::Hex8 => (9, false),
    }
}

/// Length of `/xdmf/topology` for these cells.
fn mixed_len(cells: &[(ElementKind, usize)]) -> usize {
    cells.iter().map(|&(k, n)| n * (1 + usize::from(mixed_code(k).1) + k.n_nodes())).sum()
}

/// `xdmf/<name>/<row>`: the view of row `row` of `/fields/<name>`.
pub fn view_name(field: &str, row: usize) -> String {
    format!("{}/{field}/{row}", layout::XDMF)
}

/// The XDMF text (it refers to the views [`write_views`] creates).
pub fn xdmf_text(l: &XdmfLayout) -> String {
    let mut x = String::new();
    let (n, h5) = (l.n_nodes, l.h5_name);
    let n_cells = l.n_cells();
    // The same mesh at every step.
    let topology = if l.mixed() {
        format!(
            "    <Topology TopologyType=\"Mixed\" NumberOfElements=\"{n_cells}\">\n     <DataItem Dimensions=\"{}\" NumberType=\"UInt\" Precision=\"8\" Format=\"HDF\">{h5}:/{}</DataItem>\n    </Topology>",
            mixed_len(l.cells),
            layout::XDMF_TOPOLOGY
        )
    } else {
        let (kind, count) = l.cells.first().copied().unwrap_or((ElementKind::Point1, 0));
        format!(
            "    <Topology TopologyType=\"{}\" NumberOfElements=\"{count}\">\n     <DataItem Dimensions=\"{count} {}\" NumberType=\"UInt\" Precision=\"8\" Format=\"HDF\">{h5}:/{}/{}</DataItem>\n    </Topology>",
            topology_name(kind),
            kind.n_nodes(),
            layout::CELLS,
            kind.name()
        )
    };

    let _ = writeln!(x, "<?xml version=\"1.0\" ?>");
    let _ = writeln!(x, "<Xdmf Version=\"3.0\">");
    let _ = writeln!(x, " <Domain>");
    let _ =
        writeln!(x, "  <Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">");
    for (k, (time, field_rows)) in l.steps.iter().enumerate() {
        let _ = writeln!(x, "   <Grid Name=\"step {k}\" GridType=\"Uniform\">");
        let _ = writeln!(x, "    <Time Value=\"{time:e}\"/>");
        let _ = writeln!(x, "{topology}");
        // The mesh where the bodies are: the positions written this step (finite strain),
        // else the reference coordinates.
        let position = (l.fields.iter().zip(field_rows))
            .find(|((spec, _), _)| spec.name == layout::POSITION)
            .and_then(|(_, row)| *row);
        let geometry = position
            .map_or_else(|| layout::COORDINATES.to_string(), |r| view_name(layout::POSITION, r));
        let _ = writeln!(
            x,
            "    <Geometry GeometryType=\"XYZ\">\n     <DataItem Dimensions=\"{n} 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">{h5}:/{geometry}</DataItem>\n    </Geometry>",
        );
        for ((spec, _), row) in l.fields.iter().zip(field_rows) {
            let Some(r) = row else { continue };
            let entries = match spec.location {
                Location::Nodal => n,
                Location::Cell => n_cells,
            };
            let _ = writeln!(
                x,
                "    <Attribute Name=\"{name}\" AttributeType=\"{ty}\" Center=\"{center}\">\n     <DataItem Dimensions=\"{entries} {c}\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">{h5}:/{view}</DataItem>\n    </Attribute>",
                name = spec.name,
                ty = spec.xdmf_type(l.dim),
                center = spec.xdmf_center(),
                c = spec.components,
                view = view_name(&spec.name, *r),
            );
        }
        let _ = writeln!(
            x,
            "    <Attribute Name=\"partition\" AttributeType=\"Scalar\" Center=\"Cell\">\n     <DataItem Dimensions=\"{n_cells}\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">{h5}:/{}</DataItem>\n    </Attribute>",
            layout::CELL_RANK
        );
        let _ = writeln!(x, "   </Grid>");
    }
    let _ = writeln!(x, "  </Grid>");
    let _ = writeln!(x, " </Domain>");
    let _ = writeln!(x, "</Xdmf>");
    x
}

/// Create `/xdmf` in the run's file (opened serially, read-write): a view (virtual dataset)
/// per written row of each field, and for a mesh with several cell kinds the `Mixed`
/// connectivity. An existing `/xdmf` is replaced.
pub fn write_views(file: &hdf5::File, l: &XdmfLayout) -> hdf5::Result<()> {
    if file.link_exists(layout::XDMF) {
        file.unlink(layout::XDMF)?;
    }
    let g = file.create_group(layout::XDMF)?;
    if l.mixed() {
        let mut mixed = Vec::with_capacity(mixed_len(l.cells));
        for &(kind, _) in l.cells {
            let conn =
                file.dataset(&format!("{}/{}", layout::CELLS, kind.name()))?.read_raw::<u64>()?;
            let (code, count) = mixed_code(kind);
            for cell in conn.chunks(kind.n_nodes()) {
                mixed.push(code);
                if count {
                    mixed.push(cell.len() as u64);
                }
                mixed.extend_from_slice(cell);
            }
        }
        file.new_dataset_builder().with_data(&mixed).create(layout::XDMF_TOPOLOGY)?;
    }
    for (spec, rows) in l.fields {
        let source = layout::field(&spec.name);
        let shape = file.dataset(&source)?.shape();
        let (entries, c) = (shape[1], shape[2]);
        g.create_group(&spec.name)?;
        for r in 0..(*rows).min(shape[0]) {
            file.new_dataset::<f64>()
                .virtual_map(
                    ".",
                    format!("/{source}"),
                    &*shape,
                    (r..r + 1, .., ..),
                    (entries, c),
                    (.., ..),
                )
                .shape((entries, c))
                .create(view_name(&spec.name, r).as_str())?;
        }
    }
    Ok(())
}

/// Index the run file `h5` (closed: no other handle of it may be open): create its views
/// ([`write_views`]), then write `xdmf` atomically.
pub fn write_xdmf(h5: &Path, xdmf: &Path, layout: &XdmfLayout) -> Result<()> {
    hdf5::File::open_rw(h5)
        .and_then(|f| {
            write_views(&f, layout)?;
            f.close()
        })
        .map_err(|e| Error::Io(format!("{}: XDMF views: {e}", h5.display())))?;
    let tmp = xdmf.with_extension("xdmf.tmp");
    std::fs::write(&tmp, xdmf_text(layout))
        .and_then(|_| std::fs::rename(&tmp, xdmf))
        .map_err(|e| Error::Io(format!("cannot write {}: {e}", xdmf.display())))
}
