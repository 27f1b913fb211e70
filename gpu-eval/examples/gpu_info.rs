//! Lists the Vulkan devices lightvol-gpu can see and the one it would pick
//! (the future `lightvol gpu-info`).
//!
//! ```text
//! cargo run --release -p lightvol-gpu --example gpu_info
//! LIGHTVOL_VK_DEVICE=llvmpipe cargo run --release -p lightvol-gpu --example gpu_info
//! ```

use std::process::ExitCode;

use lightvol_gpu::{DEVICE_ENV, gpu_info, select_device};

fn main() -> ExitCode {
    let devices = match gpu_info() {
        Ok(d) => d,
        Err(e) => {
            eprintln!("gpu-info: {e}");
            return ExitCode::FAILURE;
        }
    };
    if devices.is_empty() {
        println!("no Vulkan devices");
    }
    for d in &devices {
        println!("{d}");
    }
    let selector = std::env::var(DEVICE_ENV).ok();
    match select_device(&devices, selector.as_deref()) {
        Ok(i) => {
            println!("selected: [{i}] {}", devices[i].name);
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gpu-info: {e}");
            ExitCode::FAILURE
        }
    }
}
