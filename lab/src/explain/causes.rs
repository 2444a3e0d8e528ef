//! What is known of each glitch family's cause, with sources: what `gwml
//! explain` prints under its best family. A fit says which shape explains
//! the data; this table says what instrument behaviour makes that shape.

/// The likely cause of one family of transients, and where that is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cause {
    /// The family's scene in `lab/models/glitch/explain.gw` (or `noise`).
    pub family: &'static str,
    /// What is known of its origin.
    pub cause: &'static str,
    /// Where that is reported.
    pub sources: &'static str,
}

/// The cause table, one row per family and one for noise alone.
pub const CAUSES: [Cause; 8] = [
    Cause {
        family: "blip",
        cause: "unknown for most blips; short broadband transients of the instrument. A few subsets coincide with \
                auxiliary or environmental channels; blips resemble heavy binary-black-hole mergers, so a blip-like \
                trigger must be checked against the other detectors",
        sources: "Cabero et al. 2019, Class. Quantum Grav. 36 155010 (blip glitches in Advanced LIGO data); \
                  Zevin et al. 2017, Class. Quantum Grav. 34 064003 (Gravity Spy)",
    },
    Cause {
        family: "koi_fish",
        cause: "unknown; a loud blip-like transient with a low-frequency head, of the same broad population as blips",
        sources: "Zevin et al. 2017, Class. Quantum Grav. 34 064003 (Gravity Spy class descriptions)",
    },
    Cause {
        family: "whistle",
        cause: "radio-frequency beat notes: an RF signal beating against the frequency of a voltage-controlled \
                oscillator (VCO) sweeps through the band as the VCO frequency drifts",
        sources: "Nuttall et al. 2015, Class. Quantum Grav. 32 245005 (data quality of the early Advanced LIGO runs); \
                  Zevin et al. 2017 (Gravity Spy)",
    },
    Cause {
        family: "scratchy",
        cause: "trains of mid-frequency arches; related to scattered light (ground motion moving surfaces that scatter \
                light back into the beam), though not established for every Scratchy glitch",
        sources: "Zevin et al. 2017 (Gravity Spy); Soni et al. 2021, Class. Quantum Grav. 38 025016 (scattered light in O3)",
    },
    Cause {
        family: "tomte",
        cause: "unknown; short low-frequency transients named in Gravity Spy's O1 classes, with no established \
                coupling to an auxiliary channel",
        sources: "Zevin et al. 2017, Class. Quantum Grav. 34 064003 (Gravity Spy); Glanz et al. 2024 (Gravity Spy's \
                  O3 classes)",
    },
    Cause {
        family: "scattered_light",
        cause: "light scattered off a surface moving with the ground (seismic, microseismic or anthropogenic motion \
                of baffles, chambers or the reaction chain) rejoins the beam; each arch's top is the surface's \
                fastest speed, its period half the motion's",
        sources: "Accadia et al. 2010, Class. Quantum Grav. 27 194011 (scattered light in Virgo); Soni et al. 2021, \
                  Class. Quantum Grav. 38 025016 (scattered light in LIGO's O3)",
    },
    Cause {
        family: "chirp",
        cause: "astrophysical if real: a compact-binary coalescence sweeps up in frequency. Check for a coincident \
                signal in the other detectors before calling it a glitch",
        sources: "Cutler & Flanagan 1994, Phys. Rev. D 49 2658 (the inspiral and its SNR); Buonanno et al. 2009, \
                  Phys. Rev. D 80 084043 (TaylorF2); Ajith et al. 2008, Phys. Rev. D 77 104017 (IMRPhenomA: merger \
                  and ringdown)",
    },
    Cause {
        family: "noise",
        cause: "Gaussian noise of the estimated PSD explains the window as well as any family does: no glitch",
        sources: "the Laplace evidences of this fit",
    },
];

/// The cause of `family`, if the table has it.
pub fn cause_of(family: &str) -> Option<&'static Cause> {
    CAUSES.iter().find(|c| c.family == family)
}
