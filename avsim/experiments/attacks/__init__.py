"""How attacked signs fare in the closed loop: the measurements and reports of `avsim attack`.

The attack library (`avsim.attacks`) makes textures; this package measures them with the
experiments' machinery:
- `texture_eval` (`avsim attack eval`): detector confidence at fixed distances and over a
  drive-by in MuJoCo renders, and the Fig. 3-like grid; `texture_eval_report` writes its Markdown;
- `disappearance` and `drive_by_report`: per-frame drive-by metrics and their report;
- `success`: closed-loop attack success from run results, with Wilson intervals;
- `budget_success` and `budget_sweep` (`avsim attack sweep`): attack strength and closed-loop
  success as the camouflage budget grows.
"""
