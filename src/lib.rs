//! massfree: parallel finite elements for dynamic elasticity with contact, with the
//! mass-free surface layer of Hager & Wohlmuth (SIAM J. Numer. Anal. 2009).
//!
//! One module per concept; see ARCHITECTURE in README.md.

pub mod assembly;
pub mod console;
pub mod contact;
pub mod error;
pub mod fem;
pub mod io;
pub mod mass;
pub mod mesh;
pub mod partition;
pub mod petsc;
pub mod phase;
pub mod post;
pub mod scene;
pub mod simulation;
pub mod study;
pub mod time;

pub use error::{Error, Result};
