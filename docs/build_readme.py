"""Assemble README.md from the topic sections in docs/readme/ (run: python docs/build_readme.py)."""
from pathlib import Path

HERE = Path(__file__).resolve().parent / "readme"
ORDER = ["_head.md", "_results.md", "diagnose.md", "diagnose_testbench.md", "fleet.md", "friction.md", "friction_model.md", "spectral.md",
         "spectral_nufft.md", "ltv.md", "estimation.md", "particle_filter.md", "seam.md", "ilqr.md", "nn.md",
         "calibration.md", "real_data.md", "real_cogging.md", "real_calibration.md", "hardening.md",
         "builders.md", "_foundation.md", "_roadmap.md"]


def main():
    parts = []
    for name in ORDER:
        p = HERE / name
        if p.exists():
            parts.append(p.read_text().strip() + "\n")
    missing = sorted(p.name for p in HERE.glob("*.md") if p.name not in ORDER)
    if missing:
        raise SystemExit(f"docs/readme has sections not in ORDER: {missing}")
    out = HERE.parents[1] / "README.md"
    out.write_text("\n".join(parts))
    print(f"wrote {out} ({sum(len(x.splitlines()) for x in parts)} lines)")


if __name__ == "__main__":
    main()
