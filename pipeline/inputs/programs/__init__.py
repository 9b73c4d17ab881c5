"""Programs from elsewhere read as their controllers read them (docs/controllers.md): ISO STS
and RS274 G-code with its macro language, Turbo PMAC motion programs, and the moves they
command; a file is data, never run or re-rendered."""
