"""Accounts an organisation runs itself: API tokens, members and invitations, sign-in
with an optional second factor, and the audit trail."""
