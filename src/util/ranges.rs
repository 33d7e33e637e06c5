//! The physical ranges a number must lie in where it enters dropscope
//! (pipeline.toml, the run manifest, a drops.csv given to `collapse`): far
//! wider than any experiment of this kind, narrow enough that every
//! quantity computed from them is a finite number. A value outside is an
//! error naming its key (or column) and the range, never an `inf` in an
//! `ok` row. A leaf: it imports nothing of the crate.

/// An inclusive range of a quantity, in the unit its key is written in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// The smallest value allowed.
    pub min: f64,
    /// The largest value allowed.
    pub max: f64,
    /// The unit, as in messages (`mm`, `kg/m³`).
    pub unit: &'static str,
    /// What the bounds stand for, for the message.
    pub why: &'static str,
}

impl Range {
    /// `v` when finite and within the range, else the sentence saying what is allowed.
    pub fn check(&self, v: f64) -> Result<f64, String> {
        if v.is_finite() && (self.min..=self.max).contains(&v) {
            Ok(v)
        } else {
            Err(self.allowed())
        }
    }

    /// "must be a number from 0.01 to 1000 mm (…)".
    pub fn allowed(&self) -> String {
        format!(
            "must be a number from {} to {} {} ({})",
            show(self.min),
            show(self.max),
            self.unit,
            self.why
        )
    }
}

/// A number as a person reads it: `1e7`, not `10000000`; `1e308`, not
/// its 309 digits.
pub fn show(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e5).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Sphere radius (mm): a 10 µm bead to a 1 m ball.
pub const SPHERE_RADIUS_MM: Range = Range {
    min: 0.01,
    max: 1000.0,
    unit: "mm",
    why: "a 10 µm bead to a 1 m ball",
};

/// Sphere density (kg/m³): a hollow ball to beyond osmium (22 590).
pub const DENSITY_KG_M3: Range = Range {
    min: 1.0,
    max: 1e5,
    unit: "kg/m³",
    why: "a hollow ball to beyond osmium",
};

/// Young's modulus of the surface (Pa): a soft gel to beyond diamond.
pub const MODULUS_PA: Range = Range {
    min: 1.0,
    max: 1e13,
    unit: "Pa",
    why: "a soft gel to beyond diamond",
};

/// A pillar's height, width or channel (mm).
pub const PILLAR_MM: Range = Range {
    min: 1e-3,
    max: 1000.0,
    unit: "mm",
    why: "a micro-pillar to a 1 m block",
};

/// A frame rate (frames/s): the range every reader accepts from a file
/// (`source::validate::FPS_RANGE`, held equal by a test; this file imports
/// nothing of the crate).
pub const FPS: Range = Range {
    min: 0.1,
    max: 1e7,
    unit: "frames/s",
    why: "a camera's frame rate",
};

/// A scale (mm per pixel): a microscope to a satellite.
pub const MM_PER_PX: Range = Range {
    min: 1e-6,
    max: 1e4,
    unit: "mm/px",
    why: "a microscope's to a wide field's",
};

/// A release height (cm): 1 µm to 10 km.
pub const DROP_HEIGHT_CM: Range = Range {
    min: 1e-4,
    max: 1e6,
    unit: "cm",
    why: "1 µm to 10 km",
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_outside_or_not_finite_are_refused_with_the_range() {
        assert_eq!(DENSITY_KG_M3.check(7800.0), Ok(7800.0));
        for bad in [1e308, 1e-308, 0.0, -7800.0, f64::NAN, f64::INFINITY] {
            let e = DENSITY_KG_M3.check(bad).unwrap_err();
            assert!(e.contains("from 1 to 1e5 kg/m³"), "{bad}: {e}");
        }
        assert!(FPS.check(1e300).unwrap_err().contains("1e7 frames/s"));
        assert_eq!((FPS.min, FPS.max), crate::source::validate::FPS_RANGE);
        assert!(SPHERE_RADIUS_MM.check(4.5).is_ok() && SPHERE_RADIUS_MM.check(1e300).is_err());
    }
}
