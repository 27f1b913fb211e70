#![doc = include_str!("../README.md")]

pub mod accumulate;
pub mod batch;
pub mod compare;
pub mod error;
pub mod frame_inputs;
pub mod kernel;
pub mod light;
pub mod operators;
pub mod oracle;
pub mod pipeline;
pub mod proxy;
pub mod receiver_scene;
pub mod reference;
pub mod sphere_fit;
pub mod tables;
pub mod upsample;
