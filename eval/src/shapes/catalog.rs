//! The shared meshes of `data/meshes/` (design §4.2): which collection each comes from and which
//! Young's modulus it gets. design §4.2: E = 10⁵ Pa for organic shapes (animals, body parts),
//! 10⁸ Pa for everything else (buildings, parts, polyhedra); ν = 0.45 and ρ = 1000 kg/m³ for all.
//! The choice is one row per file here, and every table prints it.

use serde::{Deserialize, Serialize};

/// Poisson ratio of every shape (design §4.2).
pub const SHAPE_POISSON_RATIO: f64 = 0.45;
/// Density of every shape (kg/m³, design §4.2).
pub const SHAPE_DENSITY: f64 = 1000.0;
/// Young's modulus of a file not in the catalog unless `--young` says otherwise (Pa).
pub const DEFAULT_SHAPE_YOUNGS_MODULUS: f64 = 1e5;

/// Where a mesh comes from; the paper's Table 2 reports Thingi10K and SimReady separately.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeCollection {
    /// A Thingi10K file (raw, or a TetWild surface of one).
    Thingi10k,
    /// A classic graphics mesh (Stanford, Keenan Crane's, Oded Stein's remeshes).
    Classic,
    /// A file not in the catalog.
    Other,
}

impl ShapeCollection {
    /// "Thingi10K", "classic" or "other".
    pub fn name(self) -> &'static str {
        match self {
            ShapeCollection::Thingi10k => "Thingi10K",
            ShapeCollection::Classic => "classic",
            ShapeCollection::Other => "other",
        }
    }
}

/// The material class that picks E (design §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MaterialClass {
    /// An animal or body part: soft, E = 10⁵ Pa.
    Organic,
    /// A building, machine part or polyhedron: stiff, E = 10⁸ Pa.
    Manufactured,
}

impl MaterialClass {
    /// Young's modulus of the class (Pa).
    pub fn youngs_modulus(self) -> f64 {
        match self {
            MaterialClass::Organic => 1e5,
            MaterialClass::Manufactured => 1e8,
        }
    }

    /// "organic" or "manufactured".
    pub fn name(self) -> &'static str {
        match self {
            MaterialClass::Organic => "organic",
            MaterialClass::Manufactured => "manufactured",
        }
    }
}

/// One catalogued mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CatalogEntry {
    /// File name in `data/meshes/`.
    pub file: &'static str,
    /// What it depicts (from `data/README.md`).
    pub title: &'static str,
    /// Its collection.
    pub collection: ShapeCollection,
    /// Its material class.
    pub class: MaterialClass,
}

const fn entry(
    file: &'static str,
    title: &'static str,
    collection: ShapeCollection,
    class: MaterialClass,
) -> CatalogEntry {
    CatalogEntry {
        file,
        title,
        collection,
        class,
    }
}

use MaterialClass::{Manufactured, Organic};
use ShapeCollection::{Classic, Thingi10k};

/// The 24 shared meshes.
pub const SHARED_MESHES: [CatalogEntry; 24] = [
    entry("243015.stl", "birdhouse base", Thingi10k, Manufactured),
    entry("293137.stl", "low-poly bunny", Thingi10k, Organic),
    entry("32770.stl", "Octocat", Thingi10k, Organic),
    entry("37384.stl", "squirrel", Thingi10k, Organic),
    entry("37620.stl", "laser chess box", Thingi10k, Manufactured),
    entry("37881.stl", "pinion gear", Thingi10k, Manufactured),
    entry("40746.stl", "ghost", Thingi10k, Organic),
    entry("44395_sf.obj", "miniature chair", Thingi10k, Manufactured),
    entry("44633.stl", "2×4 brick", Thingi10k, Manufactured),
    entry("47076.stl", "stepped pyramid", Thingi10k, Manufactured),
    entry("54725_sf.obj", "Metatron lattice", Thingi10k, Manufactured),
    entry("65414.stl", "fennec fox", Thingi10k, Organic),
    entry("80084.stl", "mini dome", Thingi10k, Manufactured),
    entry(
        "93070.stl",
        "Johnson polyhedron dual",
        Thingi10k,
        Manufactured,
    ),
    entry("94492.stl", "extruder hopper", Thingi10k, Manufactured),
    entry("armadillo.obj", "armadillo", Classic, Organic),
    entry("bunny.obj", "Stanford bunny", Classic, Organic),
    entry("cat-low-resolution.obj", "cat", Classic, Organic),
    entry("goathead.obj", "goat head", Classic, Organic),
    entry("hand_closed.obj", "hand", Classic, Organic),
    entry("koala_low_resolution.obj", "koala", Classic, Organic),
    entry("scorpion_low_resolution.obj", "scorpion", Classic, Organic),
    entry("skull_low_resolution.obj", "skull", Classic, Organic),
    entry("spot_low_resolution.obj", "Spot the cow", Classic, Organic),
];

/// The catalog entry of a file name (`bunny.obj`), if it is one of the shared meshes.
pub fn catalog_entry(file_name: &str) -> Option<&'static CatalogEntry> {
    SHARED_MESHES.iter().find(|e| e.file == file_name)
}
