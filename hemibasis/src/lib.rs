//! lightvol-hemibasis (work in progress).
