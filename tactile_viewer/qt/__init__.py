"""The window: main window, menus, a module per panel, dialogs, background tasks, preferences, errors."""
