//! Experiments, metrics, tables and the `freeform` command-line interface (DESIGN 4-5).
//!
//! Will hold: the named scenes (beam Bend/Twist, Fix side, Pull farthest, Pull boundary) turned
//! into each solver's inputs, the error metrics of DESIGN 4.3, the table reproductions with the
//! paper's numbers beside ours, and the error-vs-time benchmark. Not built yet (see the eval
//! issues).
