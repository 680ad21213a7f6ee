//! Tables 2 (MSE and max error on the shapes, training time) and 7 (basis fitting residual on
//! the shapes) as typed rows ([`Table2`], [`Table7`]) rendered to Markdown with the paper's averages beside ours, JSON (`"shapes"`: one row per
//! (shape, boundary condition); `"averages"`) and CSV.
//!
//! Averages are means over the shapes where every method in the row finished the boundary
//! condition and the FEM reference passed the quality gate
//! ([`crate::shapes::result::ShapeResult::untrusted_reference`]: volume kept within
//! `ShapeStudyConfig::max_reference_volume_error`, every step converged; `n` says how many);
//! "improvement" is `(S − F) / S` of those averages, and "wins" counts the shapes where our
//! value is the lower one.

mod averages;
mod preamble;
mod shape_cells;
mod table2;
mod table2_row;
mod table7;
#[cfg(test)]
mod tests;

pub use averages::ShapeAverage;
pub use table2::{
    MeanStd, Table2, Table2Average, Table2PaperRow, Table2Row, TrainingSeconds, table2,
};
pub use table7::{Table7, Table7Row, table7};
