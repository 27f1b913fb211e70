#![doc = include_str!("../README.md")]

pub mod accumulate;
pub mod batch;
pub mod compare;
pub mod error;
pub mod fit;
pub mod kernel;
pub mod light;
pub mod operators;
pub mod oracle;
pub mod pipeline;
pub mod proxy;
pub mod reference;
pub mod scene;
pub mod tables;
pub mod upsample;
