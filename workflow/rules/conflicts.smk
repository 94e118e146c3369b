# Structured conflicts (not in the paper; madpinn/conflicts.py): every configured `conflict_*`
# study (head-on pairs, head-on lines, circle swap, crossing flows) gets its table; the evaluate
# rule runs its cells like any other study's.
for _study in ("conflict_pairs", "conflict_lines", "conflict_circle", "conflict_crossing"):
    register_table(f"table_{_study}", _study, "safety_by_n")
