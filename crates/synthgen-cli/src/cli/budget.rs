//! The training budget flags of `synthgen experiment mix` and `sim2real` (resolved by
//! `synthgen_experiment::options::TrainBudgetOptions`).

use clap::Args;

/// The training budget of every trained row, shared by `experiment mix` and `sim2real`.
#[derive(Debug, Args)]
pub struct TrainBudgetArgs {
    /// Training epochs per trained row. [default: 8; 20 for the RGB models; 2 with --quick]
    #[arg(long)]
    pub epochs: Option<usize>,

    /// Instances per step. [default: 32; 8 with --quick]
    #[arg(long)]
    pub batch: Option<usize>,

    /// Peak learning rate (AdamW, cosine schedule). [default: 1e-3; 2e-3 for the RGB models]
    #[arg(long, allow_negative_numbers = true)]
    pub lr: Option<f64>,

    /// Points sampled per object instance. [default: 500; 64 with --quick]
    #[arg(long)]
    pub points: Option<usize>,

    /// Width of the global feature. [default: 128; 16 with --quick]
    #[arg(long)]
    pub width: Option<usize>,
}
