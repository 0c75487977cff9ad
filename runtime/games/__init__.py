"""Language games over the peer channels and the joint-attention monitor that starts them."""
