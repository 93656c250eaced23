"""The configuration: the env schemas every task shares and their validation (`base`), the training
config (`train`) with its bounds (`bounds`) and recipes (`recipe`), and a checkpoint's config rebuilt
as today's (`checkpoint`). One check per setting, in the schema that holds it."""
