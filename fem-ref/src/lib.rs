//! Tetrahedral finite-element ground truth (DESIGN 3.8).
//!
//! Will hold: structured and surface-conforming tetrahedral meshes, P1/P2 elements with the
//! shared `hyperelastic` materials, and a backward-Euler Newton solver with exact Dirichlet
//! conditions and cached trajectories. Not built yet (see the fem-ref issue).
