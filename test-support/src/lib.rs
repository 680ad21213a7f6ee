#![doc = include_str!("../README.md")]

pub mod finite_difference;
pub mod fixtures;
pub mod strategies;
