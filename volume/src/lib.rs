//! lightvol-volume (work in progress).
