"""What a person looks at: plots, animations, equations as text and LaTeX."""
