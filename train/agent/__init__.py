"""The agent's maths, no I/O: the batched Q-network, the double-DQN update, replay and RND."""
