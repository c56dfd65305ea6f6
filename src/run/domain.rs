//! The run's [`Domain`]: what every phase reads and none changes.

use std::rc::Rc;

use mpi::topology::SimpleCommunicator;

use crate::bodies::Bodies;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::scene::Scene;

/// What every phase of a run reads and none changes: the communicator, the scene, the mesh
/// with its partition and bodies, and the number of steps.
pub struct Domain<'a> {
    pub world: &'a SimpleCommunicator,
    pub scene: Scene,
    /// The cells of each `[[body]]`: material and mass treatment per cell, the layer's groups.
    pub bodies: Bodies,
    /// Shared with the loads and the stress output.
    pub mesh: Rc<Mesh>,
    pub part: Rc<Partition>,
    pub rank: usize,
    pub size: usize,
    /// The steps to run: the scene's, or the command line's `--steps`.
    pub n_steps: usize,
}

impl Domain<'_> {
    /// The effects line, with the mass treatment as the mesh resolved it.
    pub fn effects(&self) -> String {
        let layer = self.bodies.layer.as_ref().map(|(k, g)| (*k, g.as_slice()));
        self.scene.effects().resolve(self.bodies.standard_masses(), layer).summary()
    }
}
