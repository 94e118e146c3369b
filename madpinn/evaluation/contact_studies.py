"""How a contact reading's study is named (issue 38): ``<base>_contacts`` flies study ``<base>``'s
cells with contacts. A leaf without MuJoCo: the workflow reads it while it plans."""

CONTACTS_SUFFIX = "_contacts"
