"""What a run leaves behind: result files, figures, report.html, transactional output folders,
provenance and honest flags."""
