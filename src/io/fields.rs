//! The output plan: which fields are written and how often (the field specs themselves are
//! plain data in [`crate::rows`]).

use crate::rows::FieldSpec;

/// A field of the output plan: its spec and its period in steps.
#[derive(Debug, Clone)]
pub struct PlannedField {
    pub spec: FieldSpec,
    pub every: usize,
}
