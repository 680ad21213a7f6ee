//! Where content-keyed caches (FEM trajectories, cubatures, trained networks) live by default.

/// The cache folder: `$FREEFORM_CACHE` if set, else `freeform-cache` in the working directory.
/// Everything in it is keyed by content and safe to delete.
pub fn default_cache_dir() -> std::path::PathBuf {
    std::env::var_os("FREEFORM_CACHE")
        .map(Into::into)
        .unwrap_or_else(|| "freeform-cache".into())
}
