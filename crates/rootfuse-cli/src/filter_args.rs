//! The filter choice shared by the commands that run one (`run`, `throughput`): name,
//! `key=value` overrides, 6D/9D and the gap limit, resolved into one [`FilterSpec`].
use clap::Args;
use rootfuse_attitude::Dof;
use rootfuse_attitude::registry::FilterSpec;

/// Which filter, with which parameters.
#[derive(Args, Debug)]
pub struct FilterArgs {
    /// Filter name (see `rootfuse filters`).
    #[arg(long)]
    pub filter: String,
    /// Parameter override `key=value` (repeatable; `rootfuse filters` lists them with units,
    /// ranges and kinds: a whole number or a switch refuses fractions).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// 6: gravity only; 9: with magnetometer (filters with a `dof` parameter). The same as
    /// `--param dof=6|9`; giving both with different values is an error.
    #[arg(long, value_parser = ["6", "9"])]
    pub dof: Option<String>,
    /// Longest accepted time step, s: a sample after a longer gap is skipped (flag 1) and the
    /// orientation held across it. The same as `--param max_dt=SECONDS` (default 1).
    #[arg(long, value_name = "SECONDS")]
    pub max_dt: Option<f64>,
}

impl FilterArgs {
    /// The spec, or one line saying what is wrong with the options.
    pub fn spec(&self) -> Result<FilterSpec, String> {
        let mut spec = FilterSpec::new(&self.filter).map_err(|e| e.to_string())?;
        for p in &self.params {
            spec.set(p).map_err(|e| e.to_string())?;
        }
        if let Some(dof) = &self.dof {
            let dof = if dof == "6" { Dof::Six } else { Dof::Nine };
            let from_param = self.param_given("dof").then(|| spec.dof()).flatten();
            if from_param.is_some_and(|d| d != dof) {
                return Err(format!(
                    "--dof {} disagrees with --param dof={}",
                    dof.count(),
                    from_param.map_or(0, Dof::count)
                ));
            }
            spec.set_dof(dof).map_err(|e| e.to_string())?;
        }
        if let Some(max_dt) = self.max_dt {
            spec.set(&format!("max_dt={max_dt}"))
                .map_err(|e| format!("--max-dt: {e}"))?;
        }
        Ok(spec)
    }

    /// True when `--dof` or `--param dof=…` asked for 6D/9D explicitly (rather than the
    /// filter's default).
    pub fn dof_explicit(&self) -> bool {
        self.dof.is_some() || self.param_given("dof")
    }

    fn param_given(&self, name: &str) -> bool {
        self.params
            .iter()
            .any(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == name))
    }
}
