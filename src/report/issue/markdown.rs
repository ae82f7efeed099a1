//! The issue as Markdown: one screen first — at most [`ONE_SCREEN_LINES`] lines before the first
//! `<details>` — then collapsed sections for what a reader opens on demand.
use super::types::Issue;

/// The lines an issue may have before its first `<details>` (a screen, as a driver engineer
/// reads it in a bug tracker).
pub const ONE_SCREEN_LINES: usize = 60;

/// The lines of `md` before its first `<details>` (all of them when it has none).
pub fn one_screen_lines(md: &str) -> usize {
    md.lines().take_while(|l| !l.trim_start().starts_with("<details>")).count()
}

/// A collapsed section: `summary`, then `body` (Markdown).
fn details(summary: &str, body: &str) -> String {
    format!("<details><summary>{summary}</summary>\n\n{}\n\n</details>\n\n", body.trim_end())
}

fn fenced(lang: &str, body: &str) -> String {
    format!("```{lang}\n{}\n```", body.trim_end())
}

impl Issue {
    pub fn markdown(&self) -> String {
        let mut m = self.screen();
        m += &self.collapsed();
        m
    }

    /// The first screen.
    fn screen(&self) -> String {
        let e = &self.environment;
        let f = &self.facts;
        let mut m = format!("# {}\n\n", self.title);
        if !self.diagnosis.is_empty() {
            m += &format!("**Diagnosis**: {}\n\n", self.diagnosis);
        }
        if let Some(i) = &self.injected {
            m += &format!("> **Note:** {i}\n\n");
        }
        m += &format!(
            "**Driver** {} {} (`driverInfo` {}), {}, Vulkan {}, conformance {}; **OS** {}, {}; **SPIR-V by** {}; rtprobe {}.\n\n",
            e.driver.split(" (").next().unwrap_or(&e.driver),
            e.driver_version,
            e.driver_info,
            e.gpu,
            e.api_version,
            e.conformance_version,
            e.os.split(" (of the machine").next().unwrap_or(&e.os),
            e.kernel,
            e.compiler,
            e.rtprobe
        );
        m += &format!("**What happens**: {}; {}.\n\n", self.actual, self.attempts);
        m += &format!("**Expected vs actual** {}\n\n", f.values);
        if let Some(sc) = &self.shader {
            m += &format!(
                "**The probed read** (`{}`; full shaders below):\n\n{}\n\n",
                sc.file,
                fenced("glsl", &sc.excerpt)
            );
        }
        m += &format!("- **Descriptors**: {}\n- **Index**: {}\n", f.layout, f.index);
        if !f.sbt.is_empty() {
            m += &format!("- **SBT**: {}\n", f.sbt);
        }
        m += &format!(
            "- **Lane evidence**: {}\n- **Validation**: {}\n- **Device fault**: {}\n\n",
            self.lanes, self.validation, self.device_fault
        );
        m += &self.isolation_screen();
        let r = &self.reproducer;
        m += &format!(
            "**Reproduce** ({}):\n\n{}\n\n{}\n\n",
            r.prints,
            fenced("sh", &r.command),
            r.without_rtprobe
        );
        let mut w: Vec<&str> = self.workarounds.iter().map(|w| w.trim_end_matches('.')).collect();
        w.push(&self.recommended_pattern);
        m += &format!("**Workarounds**: {}.\n\n", w.join("; "));
        m
    }

    /// The isolation list on the first screen.
    fn isolation_screen(&self) -> String {
        let mut m = format!(
            "**Isolation**: minimal {}: `{}`; one axis changed at a time from the failing cell (k/N attempts):\n\n",
            if self.separable { "description" } else { "description (a disjunction: no single conjunction separates the cells)" },
            self.minimal
        );
        for l in &self.isolation_summary {
            m += &format!("- {l}\n");
        }
        m + "\n"
    }

    /// The collapsed sections.
    fn collapsed(&self) -> String {
        let mut m = String::new();
        let mut iso: String = self.isolation.iter().map(|l| format!("- {l}\n")).collect();
        if !self.workaround_details.is_empty() {
            iso += "\nWorkaround patches on the minimal failing cell:\n\n";
            iso += &self.workaround_details.iter().map(|l| format!("- {l}\n")).collect::<String>();
        }
        iso += &format!("\n{}\n\n{}", self.summary, self.incidence);
        m += &details(
            "Isolation list with statistics (fault-rate bounds, miss probabilities)",
            &iso,
        );
        let e = &self.environment;
        m += &details(
            "Environment",
            &format!(
                "| | |\n|---|---|\n| GPU | {} |\n| Vendor / device id | {} / {} |\n| Driver | {} |\n| Driver version | {} |\n| Vulkan API version | {} |\n| Conformance version | {} |\n| OS | {} |\n| Kernel | {} |\n| SPIR-V compiler | {} |\n| rtprobe | {} |",
                e.gpu, e.vendor, e.device_id, e.driver, e.driver_version, e.api_version, e.conformance_version, e.os, e.kernel, e.compiler, e.rtprobe
            ),
        );
        m += &details("What rtprobe checks", &self.expected);
        if !self.heap.is_empty() {
            m += &details("Descriptor heap", &self.heap);
        }
        m += &self.shader_sections();
        let cmds: String = self.reproduce.iter().map(|r| format!("{r}\n")).collect();
        m += &details("Other reproduce commands (rtprobe)", &fenced("sh", &cmds));
        let nt: String = self.not_tested.iter().map(|n| format!("- {n}\n")).collect();
        m += &details("Not tested", &nt);
        m
    }

    fn shader_sections(&self) -> String {
        let Some(sc) = &self.shader else {
            return match &self.shader_error {
                Some(err) => {
                    details("Shaders", &format!("The shaders could not be rebuilt: {err}"))
                }
                None => String::new(),
            };
        };
        let mut m = details(
            &format!("GLSL of `{}` (`{}`, as rtprobe generates it)", sc.file, sc.failing_cell),
            &fenced("glsl", &sc.glsl),
        );
        match (&sc.passing_cell, &sc.glsl_diff) {
            (Some(p), Some(d)) => m += &details(&format!("GLSL diff from the closest passing sibling `{p}`"), &fenced("diff", d)),
            (Some(p), None) => m += &details("GLSL diff", &format!("The closest passing sibling `{p}` has the same probed GLSL (the difference is outside the shader).")),
            (None, _) => m += &details("GLSL diff", "No passing sibling was found to compare with."),
        }
        m += &details("SPIR-V disassembly of the failing shader", &fenced("", &sc.spirv));
        if let Some(d) = &sc.spirv_diff {
            m += &details(
                "SPIR-V diff from the passing sibling (numeric ids ignored when matching lines)",
                &fenced("diff", d),
            );
        }
        m
    }
}
