"""mock_hw package."""
