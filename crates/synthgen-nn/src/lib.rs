//! The candle CPU kernels synthgen's training runs on (issue 51): layers as single graph
//! nodes whose forward and backward passes are multi-threaded (rayon) and compute the values
//! of the candle ops they replace — the fused dense layer ([`fused`], [`dense`]), the fused
//! convolution over NHWC maps ([`conv`], [`im2col`]), nearest upsampling with its skip
//! concatenation ([`upsample`]), the per-pixel symmetric ADD distances ([`point_distance`]),
//! AdamW in one parallel pass ([`optim`]) — and seeded, order-independent initialization
//! ([`init`]). On other devices (CUDA) each falls back to candle's own ops.
//!
//! ```
//! use candle_core::{DType, Device, Tensor};
//! use candle_nn::{VarBuilder, VarMap};
//! use synthgen_nn::dense::dense;
//!
//! let varmap = VarMap::new();
//! let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
//! let layer = dense(3, 8, vb.pp("l1"))?;
//! let x = Tensor::ones((4, 3), DType::F32, &Device::Cpu)?;
//! assert_eq!(layer.forward_relu(&x)?.dims(), &[4, 8]);
//! # Ok::<(), candle_core::Error>(())
//! ```

pub mod conv;
pub mod dense;
pub mod fused;
pub mod im2col;
pub mod init;
pub mod optim;
pub mod point_distance;
pub mod upsample;
