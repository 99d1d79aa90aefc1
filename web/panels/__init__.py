"""The viewer's GUI panels, built per browser (`client.gui`) according to its role."""
