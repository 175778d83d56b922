//! The single steps the experiments chain, which the CLI's own commands run too: the object
//! models of a dataset in a renderer (`models`), the scene and sensor fits written to files
//! (`fit`), conversion (`convert`), a render as `synthgen render` runs it (`render`) and a replay of
//! real frames at their GT poses (`replay`) a training run (`train`) and an evaluation (`eval`).

pub mod convert;
pub mod eval;
pub mod fit;
pub mod models;
pub mod render;
pub mod replay;
pub mod train;
