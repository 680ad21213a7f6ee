//! What every table and figure shares: the paper's numbers ([`paper`]), rendered tables and
//! their files ([`table`]), and plots ([`plot`]).

pub mod paper;
pub mod plot;
pub mod table;
