"""Planning: the abstraction pyramid (`abstraction`: obstacleness per level), the
connectivity-aware abstraction (`components`: one node per connected free component of a block)
and its doors (`doors`), the general path finder (`search`: A*, the papers' baseline) and its
compiled searches (`corridor_search`), and the anytime abstract planner (`planner`: the papers'
ATP)."""
