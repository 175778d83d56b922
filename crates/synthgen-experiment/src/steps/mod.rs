//! The single steps the experiments chain, which the CLI's own commands run too: the object
//! models of a dataset in a renderer (`models`), the scene and sensor fits written to files
//! (`fit`), and conversion to BOP (`convert`).

pub mod convert;
pub mod fit;
pub mod models;
