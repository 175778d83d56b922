//! Quaternion maths on tensors, shared by the rotation heads (`models`) and their losses.

use candle_core::{Result, Tensor};

/// Unit quaternions (…, 4), (w, x, y, z), to row-major rotation matrices (…, 3, 3).
pub fn quaternion_to_matrix(q: &Tensor) -> Result<Tensor> {
    let dims = q.dims().to_vec();
    let last = dims.len() - 1;
    let part = |i: usize| q.narrow(last, i, 1);
    let (w, x, y, z) = (part(0)?, part(1)?, part(2)?, part(3)?);
    let two = |a: &Tensor, b: &Tensor| -> Result<Tensor> { (a * b)? * 2.0 };
    let (xx, yy, zz) = (two(&x, &x)?, two(&y, &y)?, two(&z, &z)?);
    let (xy, xz, yz) = (two(&x, &y)?, two(&x, &z)?, two(&y, &z)?);
    let (wx, wy, wz) = (two(&w, &x)?, two(&w, &y)?, two(&w, &z)?);
    let one_minus = |a: &Tensor, b: &Tensor| -> Result<Tensor> { 1.0 - (a + b)? };
    let entries = [
        one_minus(&yy, &zz)?,
        (&xy - &wz)?,
        (&xz + &wy)?,
        (&xy + &wz)?,
        one_minus(&xx, &zz)?,
        (&yz - &wx)?,
        (&xz - &wy)?,
        (&yz + &wx)?,
        one_minus(&xx, &yy)?,
    ];
    let m = Tensor::cat(&entries, last)?;
    let mut shape = dims[..last].to_vec();
    shape.extend([3, 3]);
    m.reshape(shape)
}
