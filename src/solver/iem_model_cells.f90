!> The cell forces of a table's chunks as every rate evaluation takes them (model_cells,
!> documented at its interface in iem_model.f90): the kernel's call for the model's
!> materials and laws (elastic, nonlinear springs, fracture; one material or several).
submodule (iem_model) iem_model_cells
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_cells
    ! no array of the cells' energies: an empty one says so (the kernel then forms no plain
    ! sum of them either)
    real(wp) :: none(0)
    if (this%nonlinear) then
      if (this%mixed) then
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, this%nl, accept, this%ks, &
                         lat%cell_mat, none, this%pw_cell, energy_terms=terms, &
                         add=.true., rows=rows, route_at=at, route=this%split%route, &
                         side=this%split%side, chunks=range, slots=slots)
      else
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, this%nl, accept, &
                         cell_energy=none, cell_power=this%pw_cell, energy_terms=terms, &
                         add=.true., rows=rows, route_at=at, &
                         route=this%split%route, side=this%split%side, &
                         chunks=range, slots=slots)
      end if
    else if (this%fracture) then
      if (this%mixed) then
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, commit=accept, ks=this%ks, &
                         cell_mat=lat%cell_mat, cell_energy=none, energy_terms=terms, &
                         cell_power=this%pw_cell, fr=this%fr, time=time, &
                         add=.true., rows=rows, route_at=at, route=this%split%route, &
                         side=this%split%side, chunks=range, slots=slots)
      else
        call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                         this%energy, pd, this%n_state - 1, commit=accept, &
                         cell_energy=none, cell_power=this%pw_cell, energy_terms=terms, &
                         fr=this%fr, time=time, add=.true., rows=rows, &
                         route_at=at, route=this%split%route, side=this%split%side, &
                         chunks=range, slots=slots)
      end if
    else if (this%mixed) then
      call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                       this%energy, pd, this%n_state - 1, ks=this%ks, &
                       cell_mat=lat%cell_mat, cell_energy=none, energy_terms=terms, &
                       cell_power=this%pw_cell, add=.true., rows=rows, &
                       route_at=at, route=this%split%route, side=this%split%side, &
                       chunks=range, slots=slots)
    else
      call cell_forces(this%k, table, lat%n_owned, y, this%beta, fs, &
                       this%energy, pd, this%n_state - 1, cell_energy=none, &
                       energy_terms=terms, &
                       cell_power=this%pw_cell, add=.true., rows=rows, &
                       route_at=at, route=this%split%route, side=this%split%side, &
                       chunks=range, slots=slots)
    end if
  end procedure model_cells
end submodule iem_model_cells
