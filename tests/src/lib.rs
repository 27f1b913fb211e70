//! Integration tests of the lightvol workspace live in `tests/tests/`; this library is empty.
