# posterior stages (wired in this file only; see workflow/rules/demo.smk for the pattern).
