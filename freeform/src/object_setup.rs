//! One object prepared for a run, the same way for a one-object scene file and for each object
//! of a scene with several: shape → integration points → basis (built for its held regions) →
//! pressure space → output maps (frames, splats, stress), then the [`Simulation`] of it.

use std::path::Path;
use std::time::Instant;

use hyperelastic::{LameParameters, MaterialField, StableNeoHookean, lame_parameters_of};
use nalgebra::Vector3;
use reduced_sim::DeformationMap;
use rkpm_core::IntegrationPoints;
use skin_eigen::{BasisParams, SkinningBasis};

use crate::frames::FrameWriter;
use crate::geometry::Geometry;
use crate::pin_hold::HeldBasisError;
use crate::pressure_space::PressureSpace;
use crate::progress::Progress;
use crate::runner::{RunError, Simulation};
use crate::scene::SceneSpec;
use crate::scene_file::{BasisSpec, GeometrySpec, MaterialSpec, SimulationSpec};
use crate::simulate_error::SimulateError;
use crate::splats::SplatTable;
use crate::stress_field::StressField;
use crate::stress_summary::StressSummary;
use rkpm_core::PointCloud;

/// What one object is: the parts of a scene file that describe it.
pub(crate) struct ObjectDescription<'a> {
    /// Its shape.
    pub(crate) geometry: &'a GeometrySpec,
    /// Scale applied after reading the shape (1: as read; a splat file keeps its scale).
    pub(crate) scale: f64,
    /// Its material.
    pub(crate) material: &'a MaterialSpec,
    /// Its basis.
    pub(crate) basis: &'a BasisSpec,
    /// The run's options (points, pins, stress, pressure, quadrature, Newton).
    pub(crate) simulation: &'a SimulationSpec,
    /// What acts on it, with its own constraints (in its rest frame).
    pub(crate) scene: &'a SceneSpec,
    /// A prefix for its status lines ("bunny: "), empty for one object.
    pub(crate) label: String,
}

/// One object ready to run: its points, material, basis and output.
pub(crate) struct ObjectSetup {
    pub(crate) geometry: Geometry,
    pub(crate) points: IntegrationPoints,
    pub(crate) material: MaterialField,
    pub(crate) basis: SkinningBasis,
    pub(crate) pressure: Option<PressureSpace>,
    /// Basis (and pressure space) build time (s).
    pub(crate) basis_seconds: f64,
}

impl ObjectSetup {
    /// Reads the shape, samples its basis and simulation points, and builds the basis for the
    /// object's hold ([`crate::PinHold::build_basis`], covering the shape's display points the
    /// frames are written at) and its pressure space.
    ///
    /// # Errors
    /// [`SimulateError`] naming the stage.
    pub(crate) fn prepare(
        object: &ObjectDescription<'_>,
        progress: &dyn Progress,
    ) -> Result<(Self, Option<SplatTable>), SimulateError> {
        let (spec, label) = (object.basis, &object.label);
        let start = Instant::now();
        let regions = if object.scene.constraints.is_empty() {
            String::new()
        } else {
            format!("; regions {}", object.simulation.pins.summary())
        };
        let volumetric = match object.simulation.pressure {
            Some(_) => "projected onto a pressure space",
            None => "pointwise",
        };
        progress.status(&format!(
            "{label}basis: m = {}, K = {}, ≈{} grid points{regions}; volumetric term {volumetric}",
            spec.modes, spec.kernels, spec.basis_points
        ));
        let (geometry, splats) = read_shape(object.geometry)?;
        // A splat file keeps its scale (validated).
        let geometry = if object.scale == 1.0 {
            geometry
        } else {
            geometry.scaled(object.scale)
        };
        let material = object.material.field();
        let fill = object.geometry.fill_interior;
        let basis_points = geometry.integration_points_filling(spec.basis_points, fill)?;
        let hold = object.simulation.pins;
        let (points, split) = hold.simulation_points(
            object.scene,
            geometry.integration_points_filling(object.simulation.simulation_points, fill)?,
        );
        if split.cut_cells > 0 {
            progress.status(&format!(
                "{label}simulation points: {} cells cut by a held region's boundary split into \
                 their held and free parts ({} points)",
                split.cut_cells,
                points.len()
            ));
        }
        let basis_params = || {
            BasisParams::default()
                .with_modes(spec.modes)
                .with_kernels(spec.kernels)
        };
        let basis_lame = lame_at(&material, basis_points.positions())?;
        let (basis, _, shared) = hold
            .build_basis_sharing(
                object.scene,
                &basis_points,
                &basis_lame,
                points.positions(),
                geometry.display_points(),
                basis_params(),
            )
            .map_err(|e| match e {
                HeldBasisError::Scene(e) => SimulateError::Run(RunError::Scene(e)),
                HeldBasisError::Basis(e) => SimulateError::Basis(e),
            })?;
        let pressure = match &object.simulation.pressure {
            None => None,
            Some(params) => Some(
                PressureSpace::build(
                    object.scene,
                    hold,
                    &basis_points,
                    &basis_lame,
                    basis_params(),
                    params,
                    shared.as_ref(),
                )
                .map_err(SimulateError::Basis)?,
            ),
        };
        let setup = ObjectSetup {
            geometry,
            points,
            material,
            basis,
            pressure,
            basis_seconds: start.elapsed().as_secs_f64(),
        };
        Ok((setup, splats))
    }

    /// The run of this object in `scene` with the options of `simulation`, cubatures cached
    /// under `cache_dir`.
    pub(crate) fn simulation<'a>(
        &'a self,
        scene: &'a SceneSpec,
        simulation: &SimulationSpec,
        cache_dir: Option<&'a Path>,
    ) -> Simulation<'a, SkinningBasis, StableNeoHookean> {
        Simulation::new(
            &self.basis,
            &self.points,
            &self.material,
            StableNeoHookean,
            scene,
        )
        .with_params(simulation.simulation_params())
        .with_quadrature(simulation.quadrature)
        .with_cache_dir(cache_dir)
        .with_pin_hold(simulation.pins)
        .with_pressure(self.pressure.as_ref())
    }

    /// The object's frames under `dir`: its surface or cloud (or, for a splat file, its
    /// splats), with the stress when `stress`.
    ///
    /// # Errors
    /// [`SimulateError`] for a map or material that cannot be evaluated.
    pub(crate) fn output(
        &self,
        dir: &Path,
        splats: Option<SplatTable>,
        stress: bool,
    ) -> Result<ObjectOutput, SimulateError> {
        let writer = FrameWriter::new(dir, &self.geometry);
        let map = DeformationMap::new(&self.basis, writer.rest_positions())
            .map_err(SimulateError::OutputMap)?;
        // The stress needs F at the integration points too, and the Lamé parameters of both.
        let stress = if stress {
            let points = self.points.positions();
            Some(StressMaps {
                point_map: DeformationMap::new(&self.basis, points)
                    .map_err(SimulateError::OutputMap)?,
                point_lame: lame_at(&self.material, points)?,
                output_lame: lame_at(&self.material, writer.rest_positions())?,
                rest_points: points.to_vec(),
            })
        } else {
            None
        };
        Ok(ObjectOutput {
            writer,
            map,
            splats,
            summary: stress.as_ref().map(|_| StressSummary {
                max_von_mises: 0.0,
                max_von_mises_output: 0.0,
                most_inverted: 0,
            }),
            stress,
            inverted_splats: 0,
            last_stress: None,
        })
    }
}

/// The Lamé parameters of `material` at `positions`.
fn lame_at(
    material: &MaterialField,
    positions: &[Vector3<f64>],
) -> Result<Vec<LameParameters>, SimulateError> {
    lame_parameters_of(&material.sample(positions)).map_err(|(_, e)| SimulateError::Material(e))
}

/// The maps the stress output needs.
struct StressMaps {
    point_map: DeformationMap,
    point_lame: Vec<LameParameters>,
    output_lame: Vec<LameParameters>,
    rest_points: Vec<Vector3<f64>>,
}

/// One object's frames: the writer, the map to its written points, its splat file, its
/// stress, and what the frames written so far had.
pub(crate) struct ObjectOutput {
    writer: FrameWriter,
    pub(crate) map: DeformationMap,
    splats: Option<SplatTable>,
    stress: Option<StressMaps>,
    /// The stress over the frames written (with stress output).
    pub(crate) summary: Option<StressSummary>,
    /// The most inverted splats in one frame.
    pub(crate) inverted_splats: usize,
    /// The stress at the output points of the last frame written.
    last_stress: Option<StressField>,
}

impl ObjectOutput {
    /// Writes frame `index` at z and time `time` (s): `frame_NNNNN.ply` / `.vtk` (or the
    /// deformed splats), and with stress `points_NNNNN.vtk`.
    ///
    /// # Errors
    /// [`SimulateError`] naming the file or the stress that could not be made.
    pub(crate) fn write(
        &mut self,
        index: usize,
        z: &[f64],
        time: f64,
    ) -> Result<(), SimulateError> {
        let x = self.map.positions(z);
        let output_stress = match (&self.stress, &mut self.summary) {
            (Some(maps), Some(summary)) => {
                let at_points = StressField::new(
                    &StableNeoHookean,
                    &maps.point_lame,
                    &maps.point_map.deformation_gradients(z),
                )?;
                self.writer.write_points(
                    index,
                    &maps.point_map.positions(z),
                    &maps.rest_points,
                    time,
                    Some(&at_points),
                )?;
                let at_output = StressField::new(
                    &StableNeoHookean,
                    &maps.output_lame,
                    &self.map.deformation_gradients(z),
                )?;
                summary.max_von_mises = summary.max_von_mises.max(at_points.max_von_mises());
                summary.max_von_mises_output =
                    summary.max_von_mises_output.max(at_output.max_von_mises());
                summary.most_inverted = summary
                    .most_inverted
                    .max(at_points.inverted.len() + at_output.inverted.len());
                Some(at_output)
            }
            _ => None,
        };
        match &self.splats {
            Some(table) => {
                let (deformed, inverted) =
                    table.deformed(&x, &self.map.deformation_gradients(z))?;
                deformed.write(&self.writer.dir().join(format!("frame_{index:05}.ply")))?;
                self.inverted_splats = self.inverted_splats.max(inverted);
            }
            None => {
                self.writer
                    .write_with_stress(index, &x, time, output_stress.as_ref())?;
            }
        }
        self.last_stress = output_stress;
        Ok(())
    }

    /// The von Mises stress (Pa) at the output points of the last frame written (with stress
    /// output).
    pub(crate) fn last_von_mises(&self) -> Option<Vec<f64>> {
        self.last_stress
            .as_ref()
            .map(|s| s.samples.iter().map(|s| s.von_mises).collect())
    }
}

/// The shape of `spec`, and for a 3DGS file its table: a splat scene reads its file once, the
/// splat centres being the cloud.
///
/// # Errors
/// [`SimulateError::Geometry`] or [`SimulateError::Splats`] naming the file.
pub(crate) fn read_shape(
    spec: &GeometrySpec,
) -> Result<(Geometry, Option<SplatTable>), SimulateError> {
    let splats = spec.splats.as_deref().map(SplatTable::read).transpose()?;
    let geometry = match &splats {
        Some(table) => Geometry::Cloud(PointCloud::new(table.positions(), None)),
        None => spec.read()?,
    };
    Ok((geometry, splats))
}
