//! XDMF 3 index of a run's HDF5 file, for ParaView: a temporal collection with one grid per
//! written step (mesh, every written field of the plan, partition). Written by rank 0 beside the `.h5`
//! at the end of a run (finished, failed or interrupted); it only points into the HDF5 file.

use std::fmt::Write as _;
use std::path::Path;

use super::{FieldSpec, Location};
use crate::error::{Error, Result};
use crate::mesh::ElementKind;

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

/// The XDMF text.
pub fn xdmf_text(l: &XdmfLayout) -> String {
    let mut x = String::new();
    let n = l.n_nodes;

    let _ = writeln!(x, "<?xml version=\"1.0\" ?>");
    let _ = writeln!(x, "<Xdmf Version=\"3.0\">");
    let _ = writeln!(x, " <Domain>");
    let _ =
        writeln!(x, "  <Grid Name=\"run\" GridType=\"Collection\" CollectionType=\"Temporal\">");
    for (k, (time, field_rows)) in l.steps.iter().enumerate() {
        let time = *time;
        let single = l.cells.len() == 1;
        if !single {
            let _ = writeln!(
                x,
                "   <Grid Name=\"step {k}\" GridType=\"Collection\" CollectionType=\"Spatial\">"
            );
            let _ = writeln!(x, "    <Time Value=\"{time:e}\"/>");
        }
        let mut first_cell = 0;
        for (kind, count) in l.cells {
            let _ = writeln!(x, "   <Grid Name=\"{} {k}\" GridType=\"Uniform\">", kind.name());
            if single {
                let _ = writeln!(x, "    <Time Value=\"{time:e}\"/>");
            }
            let nn = kind.n_nodes();
            let _ = writeln!(
                x,
                "    <Topology TopologyType=\"{}\" NumberOfElements=\"{count}\">\n     <DataItem Dimensions=\"{count} {nn}\" NumberType=\"UInt\" Precision=\"8\" Format=\"HDF\">{}:/mesh/cells/{}</DataItem>\n    </Topology>",
                topology_name(*kind),
                l.h5_name,
                kind.name()
            );
            let _ = writeln!(
                x,
                "    <Geometry GeometryType=\"XYZ\">\n     <DataItem Dimensions=\"{n} 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">{}:/mesh/coordinates</DataItem>\n    </Geometry>",
                l.h5_name
            );
            for ((spec, total), row) in l.fields.iter().zip(field_rows) {
                let Some(r) = row else { continue };
                // Nodal fields: all nodes; cell fields: this kind's cells.
                let (start, len, all) = match spec.location {
                    Location::Nodal => (0, n, n),
                    Location::Cell => (first_cell, *count, l.cells.iter().map(|c| c.1).sum()),
                };
                let _ = writeln!(
                    x,
                    "    <Attribute Name=\"{name}\" AttributeType=\"{ty}\" Center=\"{center}\">\n     <DataItem ItemType=\"HyperSlab\" Dimensions=\"{len} {c}\" Type=\"HyperSlab\">\n      <DataItem Dimensions=\"3 3\" Format=\"XML\">{r} {start} 0 1 1 1 1 {len} {c}</DataItem>\n      <DataItem Dimensions=\"{total} {all} {c}\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">{}:/fields/{name}</DataItem>\n     </DataItem>\n    </Attribute>",
                    l.h5_name,
                    name = spec.name,
                    ty = spec.xdmf_type(l.dim),
                    center = spec.xdmf_center(),
                    c = spec.components
                );
            }
            if single {
                let _ = writeln!(
                    x,
                    "    <Attribute Name=\"partition\" AttributeType=\"Scalar\" Center=\"Cell\">\n     <DataItem Dimensions=\"{count}\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">{}:/mesh/cell_rank</DataItem>\n    </Attribute>",
                    l.h5_name
                );
            }
            let _ = writeln!(x, "   </Grid>");
            first_cell += count;
        }
        if !single {
            let _ = writeln!(x, "   </Grid>");
        }
    }
    let _ = writeln!(x, "  </Grid>");
    let _ = writeln!(x, " </Domain>");
    let _ = writeln!(x, "</Xdmf>");
    x
}

/// Write `path` (the .xdmf) atomically.
pub fn write_xdmf(path: &Path, layout: &XdmfLayout) -> Result<()> {
    let tmp = path.with_extension("xdmf.tmp");
    std::fs::write(&tmp, xdmf_text(layout))
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}
