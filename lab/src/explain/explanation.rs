//! What `gwml explain` finds for a trigger: each family's fit (its
//! params with σ, χ²/dof, evidence) and the ranking of the fits against
//! each other and against noise alone.

use super::Family;
use gwml_runtime::fit::Score;

/// One fitted param.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The scene's param name.
    pub name: String,
    /// Its unit ("1" when dimensionless).
    pub unit: String,
    /// Best fit.
    pub value: f64,
    /// 1σ from the Fisher matrix (none when it has no inverse), widened by
    /// the distances to other modes of the likelihood when some are known
    /// (a scratchy carrier a comb line off, a whistle's vertex a cycle
    /// slip off), as the spread of a mixture of modes about the estimate,
    /// and for a family's `profiled` params to the profile likelihood's
    /// at ±3σ where that is flatter than a Gaussian.
    pub sigma: Option<f64>,
    /// The prior's bounds (the phase: the period around its estimate).
    pub bounds: (f64, f64),
}

/// One family's fit to a trigger.
#[derive(Clone, Debug)]
pub struct FamilyFit {
    /// The family.
    pub family: Family,
    /// Its params: `dt`, `snr`, `phi`, then the shape's.
    pub params: Vec<Estimate>,
    /// χ² of the residual per degree of freedom (samples − params).
    pub chi2_dof: f64,
    /// Loss, Laplace evidence and BIC.
    pub score: Score,
    /// The whitened best-fit model over the window.
    pub model: Vec<f64>,
    /// The params' covariance, the Fisher matrix's inverse, before any
    /// widening (none when it has no inverse).
    pub covariance: Option<Vec<Vec<f64>>>,
    /// Scene evaluations the fit took (forward, and value with gradient).
    pub evaluations: usize,
    /// Seconds the fit took, its starts' searches included (one thread).
    pub seconds: f64,
    /// Whether the fit was polished to `|ΔL| ≤ 1e-9 L` (and by Newton
    /// steps where L-BFGS ran out): every fit within `NEIGHBOUR_GATE`
    /// of the best or `NOISE_GATE` of noise alone is; the others keep their refined
    /// minimum (1e-8).
    pub polished: bool,
}

impl FamilyFit {
    /// `ln Z`, or −∞ when the fit has no evidence.
    pub fn ln_z(&self) -> f64 {
        self.score.evidence.as_ref().map_or(f64::NEG_INFINITY, |e| e.ln_z)
    }

    /// The estimate of param `name`.
    pub fn param(&self, name: &str) -> Option<&Estimate> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// Every family's fit to one trigger, best first.
#[derive(Clone, Debug)]
pub struct Explanation {
    /// The fits, by decreasing evidence: one per family, its best variant.
    pub fits: Vec<FamilyFit>,
    /// The variants of a family that fitted worse than its best (a blip
    /// with an echo where the blip alone explains more).
    pub worse_variants: Vec<FamilyFit>,
    /// The loss of noise alone, ½ Σ d²: its `ln Z` is minus this.
    pub noise_loss: f64,
    /// Samples fitted.
    pub samples: usize,
}

impl Explanation {
    /// `ln Z` of Gaussian noise alone (no params).
    pub fn ln_z_noise(&self) -> f64 {
        -self.noise_loss
    }

    /// The family with the highest evidence, if it beats noise alone.
    pub fn best(&self) -> Option<&FamilyFit> {
        self.fits.first().filter(|f| f.ln_z() > self.ln_z_noise())
    }

    /// `ln B` of a fit against the best one (≤ 0).
    pub fn ln_bayes_vs_best(&self, fit: &FamilyFit) -> f64 {
        fit.ln_z() - self.fits.first().map_or(f64::NEG_INFINITY, FamilyFit::ln_z)
    }

    /// `ln B` of a fit against noise alone.
    pub fn ln_bayes_vs_noise(&self, fit: &FamilyFit) -> f64 {
        fit.ln_z() - self.ln_z_noise()
    }

    /// Scene evaluations of all the fits (the worse variants' included).
    pub fn evaluations(&self) -> usize {
        self.fits.iter().chain(&self.worse_variants).map(|f| f.evaluations).sum()
    }
}
