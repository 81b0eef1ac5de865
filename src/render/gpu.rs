//! GPU pass of the renderer (not yet implemented).
