//! Skinning eigenmodes from RKPM shape functions (paper Sec. 3.2, Prop. 1, Eqs. 14-15).
//!
//! Will hold: assembly of the RKPM mass matrix 𝓜 and the weight-space Hessian H_w from
//! `rkpm-core` shape functions and `hyperelastic` Lamé parameters, the generalized eigen solve
//! H_w c = λ𝓜c, and the `SkinningBasis` type that evaluates the weights W(X) and ∇W(X).
//! Not built yet (see the skin-eigen issue).
