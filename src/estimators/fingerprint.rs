//! The friction fingerprint of an axis and the preload diagnosis built on it.
//!
//! Like a drive vendor's universal axis test, the fingerprint separates an axis's torque during
//! the warm-up moves into Coulomb friction (per direction), viscous friction, inertia and a
//! torque offset: τ = τ₀ + T_c·sign(ω) + B·ω + J·α, with R² as its coherence. Taken on a healthy
//! machine it is the baseline; later fingerprints are trended against it.
//!
//! Preload shows in the Coulomb part: a preloaded nut and bearing set drag with a torque that
//! depends on the preload, not on speed (catalogue drag-torque formula; Palmgren's M₁). Wear,
//! contamination and tired lubricant show in the speed-dependent part. So the diagnosis is: the
//! preload-dependent share of Coulomb friction falling → preload loss; friction rising (either
//! part) → friction rise from wear.
#![allow(non_snake_case)] // unit suffixes are part of the names

use crate::fit::{Design, ols};
use crate::profile::{AxisProfile, NutRating, ScrewProfile};
use crate::signal::channel::CUT_DEPTH;
use crate::signal::{AxisId, Quantity, Recording, axis_column};

/// rpm → rad/s.
const RPM_TO_RAD_PER_S: f64 = std::f64::consts::PI / 30.0;
/// Motor speed at which friction is compared, rpm: a typical traverse. Comparing the friction
/// torque there, rather than the viscous slope alone, stays meaningful when the slope is near
/// zero (Palmgren's speed term is concave, and warming oil flattens it further).
pub const REFERENCE_SPEED_RPM: f64 = 1000.0;

/// An axis's friction fingerprint.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrictionFingerprint {
    /// The axis.
    pub axis: AxisId,
    /// Where it was taken (file name).
    pub source: String,
    /// Coulomb friction, mean of both directions, N·m.
    pub coulomb_Nm: f64,
    /// Coulomb friction moving positive, N·m.
    pub coulomb_positive_Nm: f64,
    /// Coulomb friction moving negative, N·m (as a magnitude).
    pub coulomb_negative_Nm: f64,
    /// Viscous friction, N·m per 1000 rpm.
    pub viscous_Nm_per_krpm: f64,
    /// Inertia seen by the motor, kg·m² (needs samples during acceleration; 0 when not resolved).
    pub inertia_kgm2: f64,
    /// Torque offset (gravity on an inclined axis, a drive offset), N·m.
    pub offset_Nm: f64,
    /// Coherence: the R² of the fit.
    pub coherence: f64,
    /// Moving samples used.
    pub samples: usize,
}

impl FrictionFingerprint {
    /// Checks a fingerprint read back from a file (a stored baseline): every figure finite,
    /// frictions and inertia not negative, the coherence an R² (at most 1). A baseline that
    /// fails would make every later drift figure meaningless.
    pub fn validate(&self) -> Result<(), String> {
        let figures = [
            ("coulomb_Nm", self.coulomb_Nm, true),
            ("coulomb_positive_Nm", self.coulomb_positive_Nm, true),
            ("coulomb_negative_Nm", self.coulomb_negative_Nm, true),
            ("viscous_Nm_per_krpm", self.viscous_Nm_per_krpm, true),
            ("inertia_kgm2", self.inertia_kgm2, true),
            ("offset_Nm", self.offset_Nm, false),
            ("coherence", self.coherence, false),
        ];
        for (name, value, not_negative) in figures {
            if !value.is_finite() {
                return Err(format!("{name} is {value}, not a finite number"));
            }
            if not_negative && value < 0.0 {
                return Err(format!(
                    "{name} is {value}: a friction or inertia is never negative"
                ));
            }
        }
        if self.coherence > 1.0 {
            return Err(format!(
                "coherence is {}: an R² is at most 1",
                self.coherence
            ));
        }
        Ok(())
    }

    /// Friction torque at [`REFERENCE_SPEED_RPM`], N·m: Coulomb plus viscous there.
    pub fn friction_at_reference_Nm(&self) -> f64 {
        self.coulomb_Nm + self.viscous_Nm_per_krpm * REFERENCE_SPEED_RPM / 1000.0
    }
}

/// Why a fingerprint could not be taken.
#[derive(Debug, thiserror::Error)]
pub enum FingerprintError {
    /// A needed column is missing.
    #[error(transparent)]
    Recording(#[from] crate::signal::RecordingError),
    /// Too few moving, non-cutting samples in both directions.
    #[error(
        "{recording}: only {samples} moving samples without cutting ({positive} positive, {negative} negative); the fingerprint needs the warm-up moves in both directions"
    )]
    TooFewMoves {
        /// The recording.
        recording: String,
        /// Usable samples.
        samples: usize,
        /// Of which moving positive.
        positive: usize,
        /// Of which moving negative.
        negative: usize,
    },
    /// The regression failed.
    #[error("{0}")]
    Fit(#[from] crate::fit::FitError),
}

/// Takes the fingerprint of `axis` from the moving, non-cutting samples of a recording.
pub fn fingerprint(
    recording: &Recording,
    axis: AxisId,
) -> Result<FrictionFingerprint, FingerprintError> {
    let speed = recording.column_for(
        &axis_column(axis, Quantity::Speed),
        "the friction fingerprint",
    )?;
    let torque = recording.column_for(
        &axis_column(axis, Quantity::Torque),
        "the friction fingerprint",
    )?;
    let cutting = recording.try_column(CUT_DEPTH);
    let time = recording.time();
    let max_speed = speed.iter().fold(0.0_f64, |m, s| m.max(s.abs()));
    let threshold = (0.01 * max_speed).max(1.0);
    let n = speed.len();
    let (mut y, mut positive, mut negative, mut velocity, mut acceleration) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 1..n.saturating_sub(1) {
        if speed[i].abs() < threshold || cutting.is_some_and(|c| c[i] > 0.0) {
            continue;
        }
        let dt = time[i + 1] - time[i - 1];
        if dt <= 0.0 {
            continue;
        }
        y.push(torque[i]);
        positive.push(if speed[i] > 0.0 { 1.0 } else { 0.0 });
        negative.push(if speed[i] < 0.0 { -1.0 } else { 0.0 });
        velocity.push(speed[i] / 1000.0);
        acceleration.push((speed[i + 1] - speed[i - 1]) * RPM_TO_RAD_PER_S / dt);
    }
    let count_positive = positive.iter().filter(|p| **p > 0.0).count();
    let count_negative = negative.iter().filter(|p| **p < 0.0).count();
    if count_positive < 5 || count_negative < 5 {
        return Err(FingerprintError::TooFewMoves {
            recording: recording.source().to_string(),
            samples: y.len(),
            positive: count_positive,
            negative: count_negative,
        });
    }
    // Coulomb per direction replaces the offset: τ = T⁺·[ω>0] − T⁻·[ω<0] + B·ω + J·α, then the
    // offset is the asymmetry (T⁺ − T⁻)/2 and the Coulomb friction their mean.
    let accel_spread = {
        let mean = acceleration.iter().sum::<f64>() / acceleration.len() as f64;
        (acceleration.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / acceleration.len() as f64)
            .sqrt()
    };
    let mut columns = vec![
        ("coulomb_negative".to_string(), negative),
        ("viscous".to_string(), velocity),
    ];
    // Acceleration enters only when the recording resolves it (at 1 Hz a rapid move's ramp
    // falls between samples and the column is noise).
    let with_inertia = accel_spread > 1.0;
    if with_inertia {
        columns.push(("inertia".to_string(), acceleration));
    }
    // The intercept plays T⁺ (positive direction) with `coulomb_negative` the change for
    // negative moves: regressors [1, −[ω<0], ω, α] span the same space as [[ω>0], −[ω<0], ω, α].
    let design = Design::from_columns("torque", y, columns)?;
    let fit = ols(&design)?;
    let c = |term: &str| fit.coefficient(term).map_or(0.0, |c| c.estimate);
    let t_pos = c("const");
    // For negative moves: τ = T⁺ − k with k the `coulomb_negative` coefficient, and τ = −T⁻.
    let t_neg = c("coulomb_negative") - t_pos;
    Ok(FrictionFingerprint {
        axis,
        source: recording.source().to_string(),
        coulomb_Nm: 0.5 * (t_pos + t_neg),
        coulomb_positive_Nm: t_pos,
        coulomb_negative_Nm: t_neg,
        viscous_Nm_per_krpm: c("viscous"),
        inertia_kgm2: if with_inertia { c("inertia") } else { 0.0 },
        offset_Nm: 0.5 * (t_pos - t_neg),
        coherence: fit.r2,
        samples: fit.n,
    })
}

/// One fingerprint figure against its baseline.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FingerprintDrift {
    /// Which figure.
    pub figure: &'static str,
    /// Baseline value.
    pub baseline: f64,
    /// Current value.
    pub current: f64,
    /// The change as a torque at the reference speed, relative to the baseline's friction
    /// there (for coherence: the change of R²).
    pub change: f64,
    /// Beyond the profile's drift limit.
    pub warning: bool,
}

/// Trends a fingerprint against its baseline; `limit` is the profile's drift fraction. Every
/// change is judged relative to the baseline's friction at the reference speed, so a figure
/// that is naturally near zero (the offset, the viscous slope) does not raise alarms on noise.
pub fn drift(
    current: &FrictionFingerprint,
    baseline: &FrictionFingerprint,
    limit: f64,
) -> Vec<FingerprintDrift> {
    let scale = baseline.friction_at_reference_Nm().abs().max(1e-9);
    let krpm = REFERENCE_SPEED_RPM / 1000.0;
    [
        (
            "friction_at_1000rpm_Nm",
            baseline.friction_at_reference_Nm(),
            current.friction_at_reference_Nm(),
            1.0,
        ),
        ("coulomb_Nm", baseline.coulomb_Nm, current.coulomb_Nm, 1.0),
        (
            "viscous_Nm_per_krpm",
            baseline.viscous_Nm_per_krpm,
            current.viscous_Nm_per_krpm,
            krpm,
        ),
        ("offset_Nm", baseline.offset_Nm, current.offset_Nm, 1.0),
    ]
    .into_iter()
    .map(|(figure, b, c, torque_per_unit)| {
        let change = (c - b) * torque_per_unit / scale;
        FingerprintDrift {
            figure,
            baseline: b,
            current: c,
            change,
            warning: change.abs() > limit,
        }
    })
    .chain(std::iter::once({
        // Coherence falling means the axis no longer behaves like friction + inertia.
        let change = current.coherence - baseline.coherence;
        FingerprintDrift {
            figure: "coherence",
            baseline: baseline.coherence,
            current: current.coherence,
            change,
            warning: change < -limit,
        }
    }))
    .collect()
}

/// The state of an axis's preload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PreloadState {
    /// Within limits.
    Normal,
    /// The preload-dependent drag has fallen: preload is being lost.
    PreloadLoss,
    /// Friction has risen: wear, contamination or tired lubricant.
    FrictionRise,
}

/// The preload diagnosis with its evidence.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PreloadDiagnosis {
    /// The axis.
    pub axis: AxisId,
    /// The verdict.
    pub state: PreloadState,
    /// Estimated preload as a fraction of nominal (nut and bearings together).
    pub preload_ratio: f64,
    /// Estimated nut preload, N.
    pub nut_preload_N: f64,
    /// Friction at the reference speed as a fraction of the baseline's.
    pub friction_ratio: f64,
    /// The evidence in words.
    pub evidence: String,
}

/// The drag torque a ball-screw nut's nominal preload causes, N·m: the catalogue formula
/// T_d = 0.05·(tan β)^(−1/2)·F_a0·l / (2π) with lead angle β = atan(l / (π·d)).
pub fn nut_preload_drag_Nm(screw: &ScrewProfile, nut: &NutRating) -> f64 {
    let tan_beta = screw.lead_mm / (std::f64::consts::PI * screw.diameter_mm);
    0.05 / tan_beta.sqrt() * nut.preload_N * (screw.lead_mm / 1000.0) / (2.0 * std::f64::consts::PI)
}

/// The drag torque the nominal preloads cause, N·m: nut (catalogue formula) plus the
/// preload-dependent Palmgren term M₁ = f₁·P·d_m of both support bearings.
pub fn nominal_preload_drag_Nm(axis: &AxisProfile) -> Option<f64> {
    let nut_drag = nut_preload_drag_Nm(axis.screw.as_ref()?, axis.nut.as_ref()?);
    let m1 = |b: &crate::profile::BearingRating| b.f1 * b.preload_N * b.pitch_diameter_mm / 1000.0;
    Some(nut_drag + m1(&axis.front_bearing) + m1(&axis.back_bearing))
}

/// Diagnoses preload from a fingerprint against a healthy baseline of the same axis: the part
/// of the baseline's Coulomb friction that is not preload drag (guideways, seals) is taken as
/// unchanged, so the change of Coulomb friction is a change of preload drag.
pub fn diagnose_preload(
    current: &FrictionFingerprint,
    baseline: &FrictionFingerprint,
    axis: &AxisProfile,
) -> Option<PreloadDiagnosis> {
    let nominal = nominal_preload_drag_Nm(axis)?;
    let nut = axis.nut.as_ref()?;
    let other = (baseline.coulomb_Nm - nominal).max(0.0);
    let preload_ratio = ((current.coulomb_Nm - other) / nominal).max(0.0);
    let friction_ratio =
        current.friction_at_reference_Nm() / baseline.friction_at_reference_Nm().abs().max(1e-9);
    let limits = &axis.limits;
    let state = if preload_ratio > 1.0 + limits.friction_rise_fraction
        || friction_ratio > 1.0 + limits.friction_rise_fraction
    {
        PreloadState::FrictionRise
    } else if preload_ratio < 1.0 - limits.preload_loss_fraction {
        PreloadState::PreloadLoss
    } else {
        PreloadState::Normal
    };
    let evidence = format!(
        "Coulomb friction {:.3} N·m (baseline {:.3}, of which {:.3} preload drag at nominal preload): preload at {:.0} % of nominal; friction at {:.0} rpm {:.3} N·m ({:.0} % of baseline)",
        current.coulomb_Nm,
        baseline.coulomb_Nm,
        nominal,
        100.0 * preload_ratio,
        REFERENCE_SPEED_RPM,
        current.friction_at_reference_Nm(),
        100.0 * friction_ratio
    );
    Some(PreloadDiagnosis {
        axis: current.axis,
        state,
        preload_ratio,
        nut_preload_N: nut.preload_N * preload_ratio,
        friction_ratio,
        evidence,
    })
}
