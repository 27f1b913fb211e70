#![doc = include_str!("../README.md")]

pub mod color;
pub mod fs;
pub mod hash;
pub mod metric;
