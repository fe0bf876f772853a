"""Domain types shared by every solver: graph, instance, plan, result, validator."""
