//! lightvol-gpu (work in progress).
#![allow(unsafe_code, reason = "Vulkan through ash is unsafe FFI; every block carries a SAFETY comment")]
