//! Baselines the method is compared against (DESIGN 3.9).
//!
//! Will hold: the Simplicits-style neural skinning field (a small MLP trained on random
//! handle transforms) and the optimization ablations of Table 3; later MPM and SPH.
//! Not built yet (see the baselines issue).
