//! What every table and figure shares: the paper's numbers ([`paper`]), rendered tables and
//! their files ([`table`]), plots ([`plot`]) and the beam tables' preamble
//! ([`beam_preamble`]).

pub mod beam_preamble;
pub mod paper;
pub mod plot;
pub mod table;
