//! lightvol-sampler (work in progress).
