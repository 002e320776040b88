"""The grasp database: schema and migrations, the store holding every SQL
statement of the project, the ranking rule, the writer lock."""
