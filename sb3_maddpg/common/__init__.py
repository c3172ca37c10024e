"""What the algorithms share: the team's base algorithm, its policy's networks, the losses and the one update step,
the replay buffer, the agent layout, exploration noise, the update schedule, who is selected, and the checks and
helpers around them."""
